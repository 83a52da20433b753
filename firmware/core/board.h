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
// The longest single step interval the generator takes in a run of several steps
// (ticks); a longer step is pushed alone (count 1) and the board chains it.
static const uint32_t STEP_MAX_RUN_INTERVAL_TICKS = 0xFF00UL;

// One continuous position sample (Board::position_take).
struct ConvSample {
    uint64_t t_us;           // its conversion's start: the ALERT/RDY edge before its own
    int32_t step_position;   // the step position at t_us
    int16_t counts;          // the conversion (valid when ok)
    bool ok;                 // its result was read
    uint8_t lost;            // samples lost right before this one (the board's ring was full)
};

class Board {
public:
    // --- time -------------------------------------------------------------------
    // Monotonic microseconds since boot (64-bit: never wraps in practice).
    virtual uint64_t now_us() = 0;

    // --- serial (UART0, interrupt-driven rings on the AVR) ----------------------
    // Next received byte, or -1 when none is waiting.
    virtual int16_t serial_read() = 0;
    // The byte `offset` places after the next unread one, left in place (-1: not there
    // yet); serial_skip(n) drops the next n. The core uses them to find a STOP behind
    // bytes it cannot handle yet.
    virtual int16_t serial_peek(uint16_t offset) = 0;
    virtual void serial_skip(uint16_t n) = 0;
    // Free space in the transmit ring, in bytes.
    virtual uint16_t serial_tx_free() = 0;
    // Queue bytes for transmission; the caller checks serial_tx_free() first and
    // only writes whole frames. Returns the number of bytes accepted.
    virtual uint16_t serial_write(const uint8_t* data, uint16_t n) = 0;

    // --- stepper (A4988 driven by the step-timer ISR) ---------------------------
    virtual void motor_enable(bool on) = 0;
    // Free entries in the ring of step runs that the step ISR consumes.
    virtual uint8_t step_space() = 0;
    // Queue a run of `count` (>= 1) steps: direction (+1 or -1) and the interval of
    // each from the previous step edge (or from now, for the first step of a burst) in
    // 1/256 STEP_TICK_HZ tick, interval_q8 for the first and add_q8 more for each next
    // one; the board carries the fraction from step to step (reset when it starts from
    // idle), so edge n comes at floor(sum of intervals) ticks. Steps
    // queued while the generator runs keep its direction (moves never reverse without
    // the generator going idle first). `last` = false promises more steps: if the
    // ring runs dry before they come, the board counts a step underrun (the step train
    // paused mid-move). The ISR sets DIR at least 200 ns before the STEP edge and keeps
    // STEP high >= 1 us. A run of count > 1 must keep every step within
    // STEP_MAX_RUN_INTERVAL_TICKS; a longer step comes alone and takes several entries
    // (waits before it). Returns false, queuing nothing, when the ring lacks the room or
    // the run breaks that rule.
    virtual bool step_push(int8_t direction, uint32_t interval_q8, int16_t add_q8, uint8_t count, bool last) = 0;
    // True while queued steps remain or a step pulse is in progress.
    virtual bool step_busy() = 0;
    // Signed count of steps executed by the ISR, read atomically.
    virtual int32_t step_position() = 0;
    // Set the step count (at boot or after a halt), atomically.
    virtual void step_set_position(int32_t steps) = 0;
    // Drop every queued step at once (faults); the motor halts where it is.
    virtual void step_halt() = 0;
    // Drop the queued steps but the pending edge and `keep` more (a controlled stop then
    // queues its deceleration); returns how many were dropped and, in rest_position,
    // where the motor is once the remaining ones have run.
    virtual uint32_t step_truncate(uint8_t keep, int32_t& rest_position) = 0;
    // Nothing more follows what is queued (a stop with no deceleration left): running dry
    // is no underrun.
    virtual void step_end_train() = 0;
    // Times the ring ran dry mid-move since boot (saturating); of them, those with the
    // last step faster than cfg::START_STOP_STEPS_PER_S (steps may have been lost).
    virtual uint16_t step_underruns() = 0;
    virtual uint16_t step_fast_underruns() = 0;

    // --- heater (Timer2 PWM on a MOSFET) and sense current (AD8276, 50 mA) ------
    // Equivalent DC voltage; the heater driver sets duty (V / V_supply)^2 rounded to its
    // duty steps and returns the equivalent voltage it actually applies (0 = off). As an
    // interlock it turns the sense current off whenever the heater is on.
    virtual uint16_t heater_set_mV(uint16_t mV) = 0;
    // Enable or disable the 50 mA sense current; refused (returns false) while the
    // heater is on.
    virtual bool sense_current(bool on) = 0;

    // --- sensors ----------------------------------------------------------------
    // Start one position conversion (ADS1115, single-ended, PGA and data rate from
    // firmware/config.h). Returns false when the ADC does not answer on I2C.
    virtual bool position_start() = 0;
    // 1 = conversion read into counts, 0 = not ready yet, -1 = I2C failure.
    virtual int8_t position_poll(int16_t& counts) = 0;
    // Continuous position conversions (ADS1115 continuous mode at the configured data
    // rate, ALERT/RDY set up as its conversion-ready pulse, ~8 us low at the end of every
    // conversion). An edge interrupt takes the time and the step position at each edge
    // (the start of the next conversion) and, every `every` conversions, starts reading
    // the one just finished: a sample (position_take). on = false returns the ADC to
    // single-shot, powered down, and forgets queued samples. on = true again sets the
    // ADC up anew (a restart). Returns false when the ADC does not answer on I2C (then
    // nothing is armed).
    virtual bool position_continuous(bool on, uint8_t every) = 0;
    // The oldest finished continuous sample; false when none is ready.
    virtual bool position_take(ConvSample& s) = 0;
    // ALERT/RDY edges since continuous mode was last armed, modulo 65536 (it wraps every
    // 76 s at 860/s: callers compare and subtract), and the time of the last one (us
    // since boot; before the first edge it means nothing).
    virtual uint16_t position_edges(uint64_t& last_us) = 0;
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
    // The position record that survives resets (in .noinit on the AVR). At boot:
    // true, with the position, when the record is intact, marked valid, armed by the
    // host (ARM_RESET: it meant to reset the board), written by a firmware of the same
    // configuration (drivers/reset_cause.h), and the motor stayed energized through the
    // reset; false otherwise (power-on, brown-out, reset mid-move or unarmed, motor
    // released, another firmware). Afterwards the core keeps it current with
    // position_record().
    virtual bool position_kept(int32_t& steps) = 0;
    virtual void position_record(int32_t steps, bool valid, bool armed) = 0;
    // Error counters since boot (saturating): UART bytes lost (receiver overrun or
    // ring full), UART framing errors, I2C bus recoveries.
    virtual uint16_t uart_overruns() = 0;
    virtual uint16_t uart_frame_errors() = 0;
    virtual uint16_t i2c_recoveries() = 0;

protected:
    ~Board() {}
};

}  // namespace fw
