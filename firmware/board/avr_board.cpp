#include "avr_board.h"

#include <avr/interrupt.h>

#include "../config.h"
#include "../drivers/a4988.h"
#include "../drivers/current_source.h"
#include "../drivers/heater.h"
#include "../drivers/reset_cause.h"
#include "../hal/ads_ready.h"
#include "../hal/clock.h"
#include "../hal/gpio.h"
#include "../hal/step_timer.h"
#include "../hal/system.h"
#include "../hal/twi.h"
#include "../hal/uart.h"

namespace board {

static_assert(fw::STEP_TICK_HZ * 8UL == F_CPU, "Timer1 runs at F_CPU / 8");

AvrBoard::AvrBoard()
    : position_adc_(cfg::ADS1115_ADDRESS), reason_(proto::boot_reason::POWER_ON), kept_(false), kept_steps_(0) {}

void AvrBoard::init() {
    cli();
    hal::quiesce();
    // Why we reset, and whether the step position survived (before anything rewrites
    // the record).
    drv::ResetRecord& rec = hal::reset_record();
    const bool intact = drv::reset_record_intact(rec);
    reason_ = drv::boot_reason_from(hal::reset_flags(), intact, intact ? rec.cause : 0);
    const bool held = hal::motor_enable_held_at_reset();
    kept_ = drv::position_survives(reason_, rec, intact, held);
    kept_steps_ = kept_ ? rec.position_steps : 0;
    // Power stages first: at reset every pin floats until here (pull-downs on STEP, the
    // heater gate and the source enable cover that time; /ENABLE, see above).
    drv::a4988::init(held);
    drv::heater::init();
    drv::current_source::init();
    hal::gpio_output(hal::PIN_LED, false);
    resistance_adc_.init();
    hal::clock_init();
    hal::uart_init();
    hal::twi_init();
    hal::step_init();
    sei();
    hal::gpio_write(hal::PIN_LED, true);
}

void AvrBoard::start_watchdog() { hal::watchdog_enable(); }

uint64_t AvrBoard::now_us() { return hal::micros(); }

int16_t AvrBoard::serial_read() { return hal::uart_read(); }
int16_t AvrBoard::serial_peek(uint16_t offset) { return offset > 255 ? -1 : hal::uart_peek(static_cast<uint8_t>(offset)); }
void AvrBoard::serial_skip(uint16_t n) { hal::uart_skip(static_cast<uint8_t>(n > 255 ? 255 : n)); }
uint16_t AvrBoard::serial_tx_free() { return hal::uart_tx_free(); }
uint16_t AvrBoard::serial_write(const uint8_t* data, uint16_t n) { return hal::uart_write(data, n); }

void AvrBoard::motor_enable(bool on) { drv::a4988::enable(on); }
uint8_t AvrBoard::step_space() { return hal::step_space(); }
bool AvrBoard::step_push(int8_t direction, uint32_t interval_q8, int16_t add_q8, uint8_t count, bool last) {
    return hal::step_push(direction, interval_q8, add_q8, count, last);
}
bool AvrBoard::step_busy() { return hal::step_busy(); }
int32_t AvrBoard::step_position() { return hal::step_position(); }
void AvrBoard::step_set_position(int32_t steps) { hal::step_set_position(steps); }
void AvrBoard::step_halt() { hal::step_halt(); }
uint32_t AvrBoard::step_truncate(uint8_t keep, int32_t& rest_position) {
    return hal::step_truncate(keep, rest_position);
}
void AvrBoard::step_end_train() { hal::step_end_train(); }
uint16_t AvrBoard::step_underruns() { return hal::step_underruns(); }
uint16_t AvrBoard::step_fast_underruns() { return hal::step_fast_underruns(); }

uint16_t AvrBoard::heater_set_mV(uint16_t mV) { return drv::heater::set_mV(mV); }
bool AvrBoard::sense_current(bool on) { return drv::current_source::set(on); }

bool AvrBoard::position_start() { return position_adc_.start(); }
int8_t AvrBoard::position_poll(int16_t& counts) { return position_adc_.poll(counts); }
bool AvrBoard::position_continuous(bool on, uint8_t every) {
    hal::ads_stream_stop();  // edges from before (or of the old mode) belong to no sample
    if (!on) return position_adc_.stop_continuous();
    if (!position_adc_.start_continuous()) return false;
    hal::ads_stream_start(cfg::ADS1115_ADDRESS, every);
    return true;
}

bool AvrBoard::position_take(fw::ConvSample& s) {
    hal::twi_async_service();  // a read the bus held too long ends here (recovered)
    hal::AdsSample a;
    uint8_t lost = 0;
    if (!hal::ads_stream_take(a, lost)) return false;
    // 32-bit stamp -> 64-bit: the sample is far less than 71 minutes old
    const uint64_t now = hal::micros();
    s.t_us = now - static_cast<uint32_t>(static_cast<uint32_t>(now) - a.t_us);
    s.step_position = hal::step_position_near(a.step_position16);
    s.counts = static_cast<int16_t>((static_cast<uint16_t>(a.bytes[0]) << 8) | a.bytes[1]);
    s.ok = a.status == hal::TWI_ASYNC_OK;
    s.lost = lost;
    return true;
}

uint16_t AvrBoard::position_edges(uint64_t& last_us) {
    uint16_t edges;
    uint32_t last;
    hal::ads_stream_edges(edges, last);
    const uint64_t now = hal::micros();
    last_us = now - static_cast<uint32_t>(static_cast<uint32_t>(now) - last);
    return edges;
}

// Refused without the sense current: the conversion would measure nothing (the core
// should never ask; this keeps a core bug from reporting a bogus resistance).
bool AvrBoard::resistance_start() {
    if (!drv::current_source::on()) return false;
    resistance_adc_.start(cfg::RESISTANCE_TIMEOUT_US,
                          drv::current_source::enabled_at_us() + drv::Cs5513::FILTER_SETTLE_US);
    return true;
}
int8_t AvrBoard::resistance_poll(int32_t& counts, uint8_t& flags) { return resistance_adc_.poll(counts, flags); }

uint8_t AvrBoard::boot_reason() { return reason_; }

void AvrBoard::kick_hw_watchdog() { hal::watchdog_kick(); }

bool AvrBoard::position_kept(int32_t& steps) {
    steps = kept_steps_;
    return kept_;
}

void AvrBoard::position_record(int32_t steps, bool valid, bool armed) {
    hal::reset_record_write(drv::CAUSE_RUNNING, steps, valid, armed);
}

uint16_t AvrBoard::uart_overruns() { return hal::uart_rx_overruns(); }
uint16_t AvrBoard::uart_frame_errors() { return hal::uart_frame_errors(); }
uint16_t AvrBoard::i2c_recoveries() { return hal::twi_recoveries(); }

}  // namespace board
