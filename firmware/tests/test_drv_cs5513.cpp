// CS5513 driver: decoding of datasheet bit patterns (DS337 Table 1: bit 23 = 0,
// 22 = OF, 21 = OD, 20 = 0, 19..0 data, two's complement) and the 3-wire read against
// a model of the part that shifts a bit out after each SCLK falling edge.
#include "../core/protocol_catalogue.h"
#include "../drivers/cs5513.h"
#include "../hal/gpio.h"
#include "fake_hal.h"
#include "test_runner.h"

namespace {
struct Decoded {
    int32_t counts;
    uint8_t flags;
};
Decoded dec(uint32_t word) {
    Decoded d;
    drv::Cs5513::decode(word, d.counts, d.flags);
    return d;
}
}  // namespace

TEST(drv_cs5513_decode_positive_and_zero) {
    CHECK_EQ(dec(0x000000).counts, 0);
    CHECK_EQ(dec(0x000000).flags, 0);
    CHECK_EQ(dec(0x000001).counts, 1);
    CHECK_EQ(dec(0x07FFFF).counts, 524287);  // positive full scale
    CHECK_EQ(dec(0x012345).counts, 0x12345);
}

TEST(drv_cs5513_decode_negative) {
    CHECK_EQ(dec(0x080000).counts, -524288);  // negative full scale
    CHECK_EQ(dec(0x0FFFFF).counts, -1);
    CHECK_EQ(dec(0x080001).counts, -524287);
    CHECK_EQ(dec(0x080000).flags, 0);
}

TEST(drv_cs5513_decode_flags) {
    const Decoded of = dec(0x400000 | 0x07FFFF);  // OF with clipped positive data
    CHECK_EQ(of.counts, 524287);
    CHECK_EQ(of.flags, proto::adc_flags::RESISTANCE_OVERRANGE);
    const Decoded od = dec(0x200000 | 0x080000);
    CHECK_EQ(od.counts, -524288);
    CHECK_EQ(od.flags, proto::adc_flags::RESISTANCE_OSCILLATION);
    const Decoded both = dec(0x600000);
    CHECK_EQ(both.flags, proto::adc_flags::RESISTANCE_OVERRANGE | proto::adc_flags::RESISTANCE_OSCILLATION);
    CHECK_EQ(proto::adc_flags::RESISTANCE_OVERRANGE, 1);
    CHECK_EQ(proto::adc_flags::RESISTANCE_OSCILLATION, 2);
    // The always-zero bits 23 and 20 never leak into data or flags.
    CHECK_EQ(dec(0x900000).counts, 0);
    CHECK_EQ(dec(0x900000).flags, 0);
}

TEST(drv_cs5513_init_pins) {
    fake::reset();
    drv::Cs5513 adc;
    adc.init();
    CHECK(fake::is_output(hal::PIN_RES_CS));
    CHECK(fake::level(hal::PIN_RES_CS));  // deselected
    CHECK(fake::is_output(hal::PIN_RES_SCLK));
    CHECK(!fake::level(hal::PIN_RES_SCLK));  // idles low
    CHECK(!fake::is_output(hal::PIN_RES_SDO));
    CHECK(fake::pullup(hal::PIN_RES_SDO));
}

TEST(drv_cs5513_discards_words_before_filter_settled) {
    fake::reset();
    drv::Cs5513 adc;
    adc.init();
    // Sense current switched on at t = 0: words before FILTER_SETTLE_US still average
    // the time it was off.
    adc.start(200000, drv::Cs5513::FILTER_SETTLE_US);
    CHECK(!fake::level(hal::PIN_RES_CS));
    int32_t counts = 0;
    uint8_t flags = 0xFF;
    CHECK_EQ(adc.poll(counts, flags), 0);  // SDO high: converting
    fake::advance_us(20000);
    fake::cs5513_load(0x0AAAAA);  // too early: discarded
    CHECK_EQ(adc.poll(counts, flags), 0);
    CHECK(!fake::cs5513_word_pending());  // but clocked out (24 falling edges)
    CHECK_EQ(fake::count_writes(hal::PIN_RES_SCLK), 1 + 48);
    fake::advance_us(drv::Cs5513::FILTER_SETTLE_US);
    fake::cs5513_load(0x412345);  // OF + 0x12345
    CHECK_EQ(adc.poll(counts, flags), 1);
    CHECK_EQ(counts, 0x12345);
    CHECK_EQ(flags, proto::adc_flags::RESISTANCE_OVERRANGE);
    CHECK(!fake::level(hal::PIN_RES_SCLK));
    CHECK(!adc.busy());
}

TEST(drv_cs5513_negative_word_over_the_wire) {
    fake::reset();
    drv::Cs5513 adc;
    adc.init();
    adc.start(200000, 0);  // current long settled: the next ready word counts
    int32_t counts = 0;
    uint8_t flags = 0;
    CHECK_EQ(adc.poll(counts, flags), 0);
    fake::cs5513_load(0x2FFFFE);  // OD + (-2)
    CHECK_EQ(adc.poll(counts, flags), 1);
    CHECK_EQ(counts, -2);
    CHECK_EQ(flags, proto::adc_flags::RESISTANCE_OSCILLATION);
}

TEST(drv_cs5513_sclk_high_and_low_at_least_1us) {
    fake::reset();
    drv::Cs5513 adc;
    adc.init();
    adc.start(200000, 0);
    int32_t counts = 0;
    uint8_t flags = 0;
    fake::cs5513_load(0x055555);
    adc.poll(counts, flags);
    uint64_t last = 0;
    bool have = false;
    for (int i = 0; i < fake::pin_event_count(); ++i) {
        const fake::PinEvent& e = fake::pin_event(i);
        if (e.pin != hal::PIN_RES_SCLK || i < 3) continue;
        if (have) CHECK(e.t_us - last >= 1);
        last = e.t_us;
        have = true;
    }
    CHECK(have);
}

TEST(drv_cs5513_times_out_without_data) {
    fake::reset();
    drv::Cs5513 adc;
    adc.init();
    adc.start(200000, 0);
    int32_t counts = 0;
    uint8_t flags = 0;
    fake::advance_us(199999);
    CHECK_EQ(adc.poll(counts, flags), 0);
    fake::advance_us(1);
    CHECK_EQ(adc.poll(counts, flags), -1);
    CHECK_EQ(adc.poll(counts, flags), -1);  // not armed any more
}

TEST(drv_cs5513_times_out_while_only_early_words_arrive) {
    fake::reset();
    drv::Cs5513 adc;
    adc.init();
    adc.start(200000, 1000000);  // valid only after 1 s: unreachable within the timeout
    int32_t counts = 0;
    uint8_t flags = 0;
    fake::advance_us(100000);
    fake::cs5513_load(0x000001);
    CHECK_EQ(adc.poll(counts, flags), 0);
    fake::advance_us(100000);
    fake::cs5513_load(0x000002);
    CHECK_EQ(adc.poll(counts, flags), -1);
}

TEST(drv_cs5513_filter_settle_covers_four_slowest_conversions) {
    CHECK_EQ(drv::Cs5513::MAX_CONVERSION_US, 19125);  // 612 clocks at 32 kHz
    CHECK_EQ(drv::Cs5513::FILTER_SETTLE_US, 76500);
}

TEST(drv_cs5513_discards_a_word_waiting_at_start) {
    fake::reset();
    drv::Cs5513 adc;
    adc.init();
    adc.start(200000, 0);
    int32_t counts = 0;
    uint8_t flags = 0;
    fake::cs5513_load(0x000111);
    CHECK_EQ(adc.poll(counts, flags), 1);
    CHECK_EQ(counts, 0x111);
    // Between measurements the converter keeps going. Soon after the current came on
    // (valid_from 10 ms ago, less than a conversion) a waiting word may predate the
    // settling: it must not be used.
    fake::advance_us(50000);
    fake::cs5513_load(0x000222);
    adc.start(200000, 40000);
    CHECK(!fake::cs5513_word_pending());
    CHECK_EQ(adc.poll(counts, flags), 0);
    fake::cs5513_load(0x000333);
    CHECK_EQ(adc.poll(counts, flags), 1);
    CHECK_EQ(counts, 0x333);
    // Long settled, a waiting word (less than one conversion old) is the measurement.
    fake::advance_us(100000);
    fake::cs5513_load(0x000444);
    adc.start(200000, 40000);
    CHECK(fake::cs5513_word_pending());
    CHECK_EQ(adc.poll(counts, flags), 1);
    CHECK_EQ(counts, 0x444);
}
