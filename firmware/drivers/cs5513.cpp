#include "cs5513.h"

#include "../core/protocol_catalogue.h"
#include "../hal/clock.h"
#include "../hal/gpio.h"

namespace drv {

void Cs5513::decode(uint32_t word, int32_t& counts, uint8_t& flags) {
    int32_t v = static_cast<int32_t>(word & DATA_MASK);
    if (v & 0x80000L) v -= 0x100000L;  // sign-extend 20 bits
    counts = v;
    flags = 0;
    if (word & OF_BIT) flags |= proto::adc_flags::RESISTANCE_OVERRANGE;
    if (word & OD_BIT) flags |= proto::adc_flags::RESISTANCE_OSCILLATION;
}

Cs5513::Cs5513() : armed_(false), timeout_us_(0), valid_from_us_(0), started_at_us_(0) {}

void Cs5513::init() {
    hal::gpio_output(hal::PIN_RES_CS, true);
    hal::gpio_output(hal::PIN_RES_SCLK, false);  // SCLK idles low
    hal::gpio_input(hal::PIN_RES_SDO, true);
}

void Cs5513::start(uint32_t timeout_us, uint64_t valid_from_us) {
    hal::gpio_write(hal::PIN_RES_CS, false);
    // A word already waiting finished less than one conversion ago (the part keeps only
    // the latest). If that may have been before valid_from_us, clock it out unused.
    if (!hal::gpio_read(hal::PIN_RES_SDO) && hal::micros() < valid_from_us + MAX_CONVERSION_US) (void)clock_word();
    armed_ = true;
    timeout_us_ = timeout_us;
    valid_from_us_ = valid_from_us;
    started_at_us_ = hal::micros();
}

uint32_t Cs5513::clock_word() { return hal::res_shift_in(WORD_BITS); }

int8_t Cs5513::poll(int32_t& counts, uint8_t& flags) {
    if (!armed_) return -1;
    const uint64_t now = hal::micros();
    if (hal::gpio_read(hal::PIN_RES_SDO)) {
        if (now - started_at_us_ < timeout_us_) return 0;
        // No word in time: a read cut short (a glitch on SCLK, a word that became ready
        // mid-clocking) leaves the part holding its output register, which blocks every
        // later word. Clocking a whole word out finishes it; with nothing pending the
        // clocks are ignored.
        (void)clock_word();
        armed_ = false;
        return -1;
    }
    const uint32_t word = clock_word();  // always read: SDO stays low until we do
    if (now < valid_from_us_) {
        if (now - started_at_us_ < timeout_us_) return 0;
        armed_ = false;
        return -1;
    }
    armed_ = false;
    decode(word, counts, flags);
    return 1;
}

}  // namespace drv
