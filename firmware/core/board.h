// Board: everything the portable core needs from the hardware, and nothing more.
//
// Contract. The AVR build implements it with hal/ and drivers/ (board/avr_board.cpp);
// the native tests and the fuzz target implement it with a fake that simulates time,
// the step generator, the sensors and the serial line. The core calls it only from the
// main loop, never from an interrupt. All methods are non-blocking (at most a few
// microseconds), so the main loop keeps polling the serial line and the planner.
// Units are in the names. No dynamic allocation anywhere.
#pragma once
#include <stdint.h>

namespace fw {

// Step generator time base: intervals are counted in ticks of this frequency
// (Timer1 at F_CPU / 8 on the ATmega2560).
static const uint32_t STEP_TICK_HZ = 2000000UL;

class Board {
public:
    // --- time -------------------------------------------------------------------
    // Monotonic microseconds since boot (64-bit: never wraps in practice).
    virtual uint64_t now_us() = 0;

    // --- serial (UART0, interrupt-driven rings on the AVR) ----------------------
    // Next received byte, or -1 when none is waiting.
    virtual int16_t serial_read() = 0;
    // Free space in the transmit ring, in bytes.
    virtual uint16_t serial_tx_free() = 0;
    // Queue bytes for transmission; the caller checks serial_tx_free() first and
    // only writes whole frames. Returns the number of bytes accepted.
    virtual uint16_t serial_write(const uint8_t* data, uint16_t n) = 0;

    // --- stepper (A4988 driven by the step-timer ISR) ---------------------------
    virtual void motor_enable(bool on) = 0;
    // Free slots in the step-interval ring that the step ISR consumes.
    virtual uint8_t step_space() = 0;
    // Queue one step: direction (+1 or -1) and the interval from the previous step
    // edge (or from now, for the first step of a move) in STEP_TICK_HZ ticks. The ISR
    // sets DIR at least 200 ns before the STEP edge and keeps STEP high >= 1 us.
    virtual void step_push(int8_t direction, uint32_t interval_ticks) = 0;
    // True while queued steps remain or a step pulse is in progress.
    virtual bool step_busy() = 0;
    // Signed count of steps executed by the ISR, read atomically.
    virtual int32_t step_position() = 0;
    // Set the step count (at boot or after a halt), atomically.
    virtual void step_set_position(int32_t steps) = 0;
    // Drop every queued step at once (STOP, faults); the motor halts where it is.
    virtual void step_halt() = 0;

    // --- heater (Timer2 PWM on a MOSFET) and sense current (AD8276, 50 mA) ------
    // Equivalent DC voltage; the heater driver sets duty (V / V_supply)^2 and, as an
    // interlock, turns the sense current off whenever the heater is on.
    virtual void heater_set_mV(uint16_t mV) = 0;
    // Enable or disable the 50 mA sense current; refused (returns false) while the
    // heater is on.
    virtual bool sense_current(bool on) = 0;

    // --- sensors ----------------------------------------------------------------
    // Start one position conversion (ADS1115, single-ended, PGA and data rate from
    // firmware/config.h). Returns false when the ADC does not answer on I2C.
    virtual bool position_start() = 0;
    // 1 = conversion read into counts, 0 = not ready yet, -1 = I2C failure.
    virtual int8_t position_poll(int16_t& counts) = 0;
    // Start one resistance conversion (CS5513); the sense current must be on and
    // settled (the core waits config RESISTANCE_SETTLE_US after enabling it).
    virtual bool resistance_start() = 0;
    // 1 = conversion read: 20-bit two's-complement counts and flags (bit 0 overrange
    // OF, bit 1 oscillation OD, as proto::adc_flags); 0 = not ready; -1 = timeout.
    virtual int8_t resistance_poll(int32_t& counts, uint8_t& flags) = 0;

    // --- system -----------------------------------------------------------------
    // Why the MCU last reset, as proto::boot_reason.
    virtual uint8_t boot_reason() = 0;
    // Feed the hardware watchdog (the AVR WDT catches a hung main loop).
    virtual void kick_hw_watchdog() = 0;

protected:
    ~Board() {}
};

}  // namespace fw
