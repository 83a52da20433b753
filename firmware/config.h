// Bench constants compiled into the firmware. The values mirror
// configs/bench/arduino-mega.yaml (tests/firmware/test_firmware_config.py checks they
// agree); the device reports them in IDENTITY and enforces the limits itself.
#pragma once
#include <stdint.h>

namespace cfg {

// Firmware version reported in BOOT and IDENTITY.
static const uint8_t FW_MAJOR = 0;
static const uint8_t FW_MINOR = 2;
static const uint8_t FW_PATCH = 0;

// Serial: UART0 at 250000 baud with U2X (0 % error at 16 MHz).
static const uint32_t BAUD = 250000UL;

// NEMA 17HS4401 (200 full steps/turn) with the A4988 at 1/16 microstepping.
static const uint16_t STEPS_PER_TURN = 3200;
static const uint8_t MICROSTEPS = 16;  // MS1..MS3 hard-wired high (firmware/README.md)
static_assert(STEPS_PER_TURN % MICROSTEPS == 0, "whole full steps per turn");
// Twist limits: -10 .. 100 turns.
static const int32_t MIN_TWIST_STEPS = -32000L;
static const int32_t MAX_TWIST_STEPS = 320000L;
// 5 turns/s and 100 turns/s^2.
static const uint32_t MAX_RATE_STEPS_PER_S = 16000UL;
static const uint32_t MAX_ACCEL_STEPS_PER_S2 = 320000UL;
// The start/stop speed: sqrt(2 a_max), the speed one step from rest at a_max. The motor
// stops from it (or pauses, a step underrun) without losing steps; a pause above it
// makes the position suspect.
static const uint32_t START_STOP_STEPS_PER_S = 800UL;
static_assert(START_STOP_STEPS_PER_S * START_STOP_STEPS_PER_S == 2 * MAX_ACCEL_STEPS_PER_S2, "sqrt(2 a_max)");

// Heater: equivalent DC voltage limit and the MOSFET's supply voltage
// (PWM duty = (V / V_supply)^2).
static const uint16_t MAX_HEATER_MV = 12000;
static const uint16_t HEATER_SUPPLY_MV = 24000;

// Command queue and host watchdog.
static const uint8_t QUEUE_SLOTS = 16;
static const uint16_t WATCHDOG_MS = 2000;
// A half frame is dropped when the next byte takes longer than this.
static const uint32_t FRAME_TIMEOUT_US = 20000UL;
// Sampling periods (0 = off). The shortest is one ADS1115 conversion at 860 samples/s
// (data sheet SBAS444, DR = 111: 1/860 s, rounded up); a shorter one is refused
// too_fast_for_sensor, and one whose sample frames would need more than
// SAMPLE_LINE_BUDGET_PERCENT of the line too_fast_for_line (core/sampling_limits.h).
static const uint32_t ADS1115_SPS = 860UL;
static const uint32_t MIN_SAMPLE_PERIOD_US = 1163UL;
static_assert(MIN_SAMPLE_PERIOD_US == (1000000UL + ADS1115_SPS - 1) / ADS1115_SPS, "one conversion, rounded up");
// From this period up, each sample is a single-shot conversion on the device's own grid
// and goes out as one SAMPLE frame: the shortest period at which every slot gets its
// sample while the motor runs at MAX_RATE_STEPS_PER_S (a conversion plus the I2C traffic
// at 400 kHz take ~1.6 ms). Below it the ADS1115 converts continuously, paced by its
// ALERT/RDY pin, and samples go out in SAMPLE_BLOCK frames.
static const uint32_t SINGLE_SHOT_MIN_PERIOD_US = 3000UL;
// Continuous sampling's liveness: no ALERT/RDY edge for this many conversions sets the
// ADS1115 up again (EVENT sensor_restarted); none for SENSOR_DEAD_US trips fault
// position_sensor, and the set-up is then retried every SENSOR_RETRY_US.
static const uint32_t SENSOR_SILENCE_CONVERSIONS = 3;
static const uint32_t SENSOR_DEAD_US = 200000UL;
static const uint32_t SENSOR_RETRY_US = 100000UL;
// Share of the line's bytes that sample frames may take (ACK, EVENT, QUEUE_STATUS need the rest).
static const uint32_t SAMPLE_LINE_BUDGET_PERCENT = 80UL;

// A latched fault holds the motor this long, then the motor is de-energized (position
// unknown from then on), the sense current and sampling go off (EVENT motor_released).
// 0 = never release.
static const uint32_t FAULT_RELEASE_MS = 10000UL;
// A controlled stop lets the queued steps of the next STOP_KEEP_US run before its
// deceleration starts, at least STOP_KEEP_STEPS and at most STOP_KEEP_MAX_STEPS (they
// are already at the current speed; the main loop needs that long to plan and queue the
// deceleration without a gap: with two steps kept, 125 us at 16,000 steps/s, the train
// ran dry at speed in simavr).
static const uint8_t STOP_KEEP_STEPS = 2;
static const uint8_t STOP_KEEP_MAX_STEPS = 16;
static const uint32_t STOP_KEEP_US = 1000UL;

// ADS1115 at I2C 0x48, single-ended AIN0, PGA +-6.144 V (config bits PGA = 000),
// 860 samples/s (DR = 111): 187.5 uV/count, conversion ~1.2 ms.
static const uint8_t ADS1115_ADDRESS = 0x48;
static const uint8_t ADS1115_PGA_BITS = 0x0;
static const uint8_t ADS1115_DR_BITS = 0x7;

// AD8276 50 mA current source: settling time after enable before a CS5513 conversion.
static const uint32_t RESISTANCE_SETTLE_US = 2000UL;
// A CS5513 conversion that has not finished after this long is a fault.
static const uint32_t RESISTANCE_TIMEOUT_US = 200000UL;

}  // namespace cfg
