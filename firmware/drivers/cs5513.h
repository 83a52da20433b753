// CS5513 20-bit delta-sigma ADC (internal oscillator), read over its 3-wire port.
//
// Contract. Data sheet DS337 (CS5510/11/12/13), Table 1, the 24-bit output word MSB
// first: bit 23 = 0, bit 22 = OF (overrange), bit 21 = OD (oscillation detect),
// bit 20 = 0, bits 19..0 = the conversion, two's complement (bipolar). With /CS low the
// converter runs continuously and SDO falls when a word is ready; the word is then
// clocked out with 24 SCLK pulses (SDO changes after SCLK falls, we sample while SCLK
// is high). /CS stays low between conversions so the sinc4 filter keeps running (after
// waking it needs four conversions to settle).
//
// start(timeout_us, valid_from_us) arms one measurement. A word already waiting at
// start() finished within the last conversion period (the part keeps only the latest):
// it is used, unless start() comes less than one conversion after valid_from_us, when
// it may predate the settling and is clocked out unused. Words that become ready
// before valid_from_us are clocked out and discarded: a word is the sinc4 filter's
// output over about four conversion periods, so after the sense current switches on
// the first words still average the time it was off. The board passes
// valid_from_us = current enable time + FILTER_SETTLE_US (four conversions at the
// slowest on-chip oscillator, 32 kHz: 53 Sps); once the current has been on that long,
// the next ready word is used at once. poll(): 0 = not ready, 1 = counts/flags valid,
// -1 = no valid word within timeout_us of start() (also when the ADC is absent: SDO
// has a pull-up); a time-out clocks one word out, so a read left half done (the part
// then holds its output register and every later word is lost) is finished. Reading a word clocks 24 bits in (hal::res_shift_in, ~30 us on the AVR).
// The core still waits cfg::RESISTANCE_SETTLE_US for the analog source to settle.
#pragma once
#include <stdint.h>

namespace drv {

class Cs5513 {
public:
    static const uint8_t WORD_BITS = 24;
    static const uint32_t OF_BIT = 1UL << 22;
    static const uint32_t OD_BIT = 1UL << 21;
    static const uint32_t DATA_MASK = 0xFFFFFUL;
    // CLK / 612 conversions; the CS5511/13 oscillator runs 32..96 kHz.
    static const uint32_t MAX_CONVERSION_US = 612UL * 1000000UL / 32000UL;  // 19125
    static const uint32_t FILTER_SETTLE_US = 4 * MAX_CONVERSION_US;         // 76500

    // Split a raw 24-bit word into signed counts and proto::adc_flags bits.
    static void decode(uint32_t word, int32_t& counts, uint8_t& flags);

    Cs5513();
    void init();
    void start(uint32_t timeout_us, uint64_t valid_from_us);
    int8_t poll(int32_t& counts, uint8_t& flags);
    bool busy() const { return armed_; }

private:
    uint32_t clock_word();
    bool armed_;
    uint32_t timeout_us_;
    uint64_t valid_from_us_;
    uint64_t started_at_us_;
};

}  // namespace drv
