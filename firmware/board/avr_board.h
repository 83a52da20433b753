// AvrBoard: fw::Board on the Arduino Mega 2560 with hal/ and drivers/.
//
// Contract. init() brings up every peripheral in a safe order (motor disabled, heater
// and sense current off before anything else, then clocks, UART, TWI, step timer) and
// enables interrupts; it does not arm the watchdog (start_watchdog(), called once boot
// output is queued, so a slow first boot cannot reset-loop). All Board methods are
// called from the main loop only. Blocking exceptions to "a few microseconds": an
// ADS1115 poll does up to two I2C exchanges (~60-100 us each at 400 kHz, bounded by
// hal::TWI_TIMEOUT_US) and a ready CS5513 word costs ~60 us of bit-banging.
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
    uint16_t serial_tx_free() override;
    uint16_t serial_write(const uint8_t* data, uint16_t n) override;

    void motor_enable(bool on) override;
    uint8_t step_space() override;
    void step_push(int8_t direction, uint32_t interval_ticks) override;
    bool step_busy() override;
    int32_t step_position() override;
    void step_set_position(int32_t steps) override;
    void step_halt() override;

    void heater_set_mV(uint16_t mV) override;
    bool sense_current(bool on) override;

    bool position_start() override;
    int8_t position_poll(int16_t& counts) override;
    bool resistance_start() override;
    int8_t resistance_poll(int32_t& counts, uint8_t& flags) override;

    uint8_t boot_reason() override;
    void kick_hw_watchdog() override;

private:
    drv::Ads1115 position_adc_;
    drv::Cs5513 resistance_adc_;
};

}  // namespace board
