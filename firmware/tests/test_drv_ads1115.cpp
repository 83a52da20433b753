// ADS1115 driver: exact config word, I2C transactions, OS polling, sign, failures.
#include "../config.h"
#include "../drivers/ads1115.h"
#include "fake_hal.h"
#include "test_runner.h"

namespace {
void queue16(uint16_t v) {
    const uint8_t b[2] = {static_cast<uint8_t>(v >> 8), static_cast<uint8_t>(v & 0xFF)};
    fake::i2c_queue_read(b, 2);
}
}  // namespace

TEST(drv_ads1115_config_word_bits) {
    // OS=1 | MUX=100 (AIN0/GND) | PGA=000 | MODE=1 | DR=111 | COMP_MODE/POL/LAT=0 | QUE=11
    CHECK_EQ(drv::Ads1115::config_word(0x0, 0x7), 0xC1E3);
    // Defaults-like values land in the right fields: PGA=010 (+-2.048 V), DR=100 (128 SPS).
    CHECK_EQ(drv::Ads1115::config_word(0x2, 0x4), 0xC583);
    CHECK_EQ(drv::Ads1115::config_word(cfg::ADS1115_PGA_BITS, cfg::ADS1115_DR_BITS) & 0x7000, 0x4000);
}

TEST(drv_ads1115_conversion_wait_covers_data_rate) {
    CHECK(drv::Ads1115::conversion_wait_us(7) >= 1163);   // 860 SPS
    CHECK(drv::Ads1115::conversion_wait_us(7) < 1500);
    CHECK(drv::Ads1115::conversion_wait_us(0) >= 125000);  // 8 SPS
}

TEST(drv_ads1115_start_writes_config_register) {
    fake::reset();
    drv::Ads1115 adc(0x48);
    CHECK(adc.start());
    CHECK_EQ(fake::i2c_event_count(), 1);
    const fake::I2cEvent& e = fake::i2c_event(0);
    CHECK(!e.is_read);
    CHECK_EQ(e.address, 0x48);
    CHECK_EQ(e.n, 3);
    CHECK_EQ(e.data[0], 0x01);  // pointer: config
    CHECK_EQ(e.data[1], 0xC1);
    CHECK_EQ(e.data[2], 0xE3);
}

TEST(drv_ads1115_poll_waits_then_reads_conversion) {
    fake::reset();
    drv::Ads1115 adc(0x48);
    CHECK(adc.start());
    int16_t counts = 0;
    CHECK_EQ(adc.poll(counts), 0);  // too early: no I2C traffic
    CHECK_EQ(fake::i2c_event_count(), 1);
    fake::advance_us(1400);
    queue16(0x41E3);  // OS=0: still converting
    CHECK_EQ(adc.poll(counts), 0);
    fake::advance_us(200);
    queue16(0xC1E3);  // OS=1: done
    queue16(0x8000);  // negative full scale
    CHECK_EQ(adc.poll(counts), 1);
    CHECK_EQ(counts, -32768);
    // Last transactions: pointer 0x00 written, then 2 bytes read.
    const int n = fake::i2c_event_count();
    CHECK(!fake::i2c_event(n - 2).is_read);
    CHECK_EQ(fake::i2c_event(n - 2).data[0], 0x00);
    CHECK(fake::i2c_event(n - 1).is_read);
    CHECK_EQ(fake::i2c_event(n - 1).n, 2);
}

TEST(drv_ads1115_big_endian_positive) {
    fake::reset();
    drv::Ads1115 adc(0x48);
    CHECK(adc.start());
    fake::advance_us(5000);
    queue16(0xC1E3);
    queue16(0x1234);
    int16_t counts = 0;
    CHECK_EQ(adc.poll(counts), 1);
    CHECK_EQ(counts, 0x1234);
    CHECK_EQ(adc.poll(counts), -1);  // not started again
}

TEST(drv_ads1115_nack_fails_start_and_poll) {
    fake::reset();
    fake::i2c_nack_address(0x48);
    drv::Ads1115 adc(0x48);
    CHECK(!adc.start());
    int16_t counts = 0;
    CHECK_EQ(adc.poll(counts), -1);
}

TEST(drv_ads1115_stuck_busy_times_out) {
    fake::reset();
    drv::Ads1115 adc(0x48);
    CHECK(adc.start());
    int16_t counts = 0;
    fake::advance_us(2000);
    queue16(0x41E3);
    CHECK_EQ(adc.poll(counts), 0);
    fake::advance_us(drv::Ads1115::CONVERSION_TIMEOUT_US);
    queue16(0x41E3);
    CHECK_EQ(adc.poll(counts), -1);
}
