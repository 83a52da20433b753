// AvrBoard: fw::Board on the Arduino Mega 2560 with hal/ and drivers/.
//
// Contract. init() first quiesces every interrupt source (the watchdog ISR restarts
// the application without a hardware reset), then brings up every peripheral in a safe
// order (STEP low, the A4988 left energized if it stayed so through the reset, heater
// and sense current off, then clocks, UART, TWI, step timer) and enables interrupts;
// it decodes the reset cause and the position record (drivers/reset_cause.h). It does
// not arm the watchdog (start_watchdog(), called once boot output is queued, so a slow
// first boot cannot trip it). All Board methods are called from the main loop only.
// Blocking exceptions to "a few microseconds": an ADS1115 poll does up to two I2C
// exchanges (~60-100 us each at 400 kHz, bounded by hal::TWI_TIMEOUT_US), a ready
// CS5513 word costs ~30 us of bit-banging, an I2C bus recovery ~100 us.
#pragma once
#include <stdint.h>

#include "../core/board.h"
#include "../drivers/ads1115.h"
#include "../drivers/cs5513.h"

namespace board {

class AvrBoard final : public fw::Board {
public:
    AvrBoard();
    void init();
    void start_watchdog();

    uint64_t now_us() override;
    int16_t serial_read() override;
    int16_t serial_peek(uint16_t offset) override;
    void serial_skip(uint16_t n) override;
    uint16_t serial_tx_free() override;
    uint16_t serial_write(const uint8_t* data, uint16_t n) override;

    void motor_enable(bool on) override;
    uint8_t step_space() override;
    bool step_push(int8_t direction, uint32_t interval_q8, int16_t add_q8, uint8_t count, bool last) override;
    bool step_busy() override;
    int32_t step_position() override;
    void step_set_position(int32_t steps) override;
    void step_halt() override;
    uint32_t step_truncate(uint8_t keep, int32_t& rest_position) override;
    void step_end_train() override;
    uint16_t step_underruns() override;
    uint16_t step_fast_underruns() override;

    uint16_t heater_set_mV(uint16_t mV) override;
    bool sense_current(bool on) override;

    bool position_start() override;
    int8_t position_poll(int16_t& counts) override;
    bool position_continuous(bool on, uint8_t every) override;
    bool position_take(fw::ConvSample& s) override;
    uint16_t position_edges(uint64_t& last_us) override;
    bool resistance_start() override;
    int8_t resistance_poll(int32_t& counts, uint8_t& flags) override;

    uint8_t boot_reason() override;
    void kick_hw_watchdog() override;
    bool position_kept(int32_t& steps) override;
    void position_record(int32_t steps, bool valid, bool armed) override;
    uint16_t uart_overruns() override;
    uint16_t uart_frame_errors() override;
    uint16_t i2c_recoveries() override;

private:
    drv::Ads1115 position_adc_;
    drv::Cs5513 resistance_adc_;
    uint8_t reason_;
    bool kept_;
    int32_t kept_steps_;
};

}  // namespace board
