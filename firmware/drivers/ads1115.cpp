#include "ads1115.h"

#include "../config.h"
#include "../hal/clock.h"
#include "../hal/twi.h"

namespace drv {

namespace {
const uint16_t CFG_OS_START = 1u << 15;
const uint16_t CFG_MUX_AIN0_GND = 0x4u << 12;
const uint8_t CFG_PGA_SHIFT = 9;
const uint16_t CFG_MODE_SINGLE = 1u << 8;
const uint8_t CFG_DR_SHIFT = 5;
const uint16_t CFG_COMP_QUE_DISABLE = 0x3u;  // COMP_MODE/POL/LAT = 0 (defaults)
// Samples per second for DR = 000 .. 111.
constexpr uint16_t SPS[8] = {8, 16, 32, 64, 128, 250, 475, 860};
constexpr uint32_t wait_for(uint16_t sps) {
    return 1000000UL / sps + (1000000UL / sps) / 10 + 100;
}
// poll() runs every main-loop pass: the configured wait is a constant, not a division.
constexpr uint32_t CONFIGURED_WAIT_US = wait_for(SPS[cfg::ADS1115_DR_BITS & 0x7u]);
}  // namespace

uint16_t Ads1115::config_word(uint8_t pga_bits, uint8_t dr_bits) {
    return static_cast<uint16_t>(CFG_OS_START | CFG_MUX_AIN0_GND |
                                 ((pga_bits & 0x7u) << CFG_PGA_SHIFT) | CFG_MODE_SINGLE |
                                 ((dr_bits & 0x7u) << CFG_DR_SHIFT) | CFG_COMP_QUE_DISABLE);
}

uint32_t Ads1115::conversion_wait_us(uint8_t dr_bits) {
    return wait_for(SPS[dr_bits & 0x7u]);
}

Ads1115::Ads1115(uint8_t address7) : address_(address7), started_(false), started_at_us_(0) {}

bool Ads1115::start() {
    const uint16_t cfg = config_word(cfg::ADS1115_PGA_BITS, cfg::ADS1115_DR_BITS);
    const uint8_t frame[3] = {REG_CONFIG, static_cast<uint8_t>(cfg >> 8), static_cast<uint8_t>(cfg & 0xFF)};
    started_ = hal::twi_write(address_, frame, sizeof frame);
    started_at_us_ = static_cast<uint32_t>(hal::micros());
    return started_;
}

bool Ads1115::read_register(uint8_t reg, uint16_t& value) {
    uint8_t rx[2];
    if (!hal::twi_write(address_, &reg, 1)) return false;
    if (!hal::twi_read(address_, rx, 2)) return false;
    value = static_cast<uint16_t>((static_cast<uint16_t>(rx[0]) << 8) | rx[1]);
    return true;
}

uint16_t Ads1115::continuous_config_word(uint8_t pga_bits, uint8_t dr_bits) {
    // OS = 0, MODE = 0 (continuous), COMP_QUE = 00 (ALERT/RDY on, every conversion)
    return static_cast<uint16_t>(CFG_MUX_AIN0_GND | ((pga_bits & 0x7u) << CFG_PGA_SHIFT) |
                                 ((dr_bits & 0x7u) << CFG_DR_SHIFT));
}

bool Ads1115::write_register(uint8_t reg, uint16_t value) {
    const uint8_t frame[3] = {reg, static_cast<uint8_t>(value >> 8), static_cast<uint8_t>(value & 0xFF)};
    return hal::twi_write(address_, frame, sizeof frame);
}

bool Ads1115::start_continuous() {
    started_ = false;
    const uint8_t pointer = REG_CONVERSION;
    return write_register(REG_LO_THRESH, 0x0000) && write_register(REG_HI_THRESH, 0x8000) &&
           write_register(REG_CONFIG, continuous_config_word(cfg::ADS1115_PGA_BITS, cfg::ADS1115_DR_BITS)) &&
           hal::twi_write(address_, &pointer, 1);
}

bool Ads1115::stop_continuous() {
    const uint16_t single = static_cast<uint16_t>(config_word(cfg::ADS1115_PGA_BITS, cfg::ADS1115_DR_BITS) & ~CFG_OS_START);
    return write_register(REG_CONFIG, single);
}

bool Ads1115::read_latest(int16_t& counts) {
    uint8_t rx[2];
    if (!hal::twi_read(address_, rx, 2)) return false;
    counts = static_cast<int16_t>((static_cast<uint16_t>(rx[0]) << 8) | rx[1]);
    return true;
}

int8_t Ads1115::poll(int16_t& counts) {
    if (!started_) return -1;
    // 32-bit modular difference: exact for waits far below the 71-minute wrap.
    const uint32_t elapsed = static_cast<uint32_t>(hal::micros()) - started_at_us_;
    if (elapsed < CONFIGURED_WAIT_US) return 0;
    uint16_t value;
    if (!read_register(REG_CONFIG, value)) {
        started_ = false;
        return -1;
    }
    if (!(value & CFG_OS_START)) {  // OS reads 0 while converting
        if (elapsed < CONVERSION_TIMEOUT_US) return 0;
        started_ = false;
        return -1;
    }
    if (!read_register(REG_CONVERSION, value)) {
        started_ = false;
        return -1;
    }
    started_ = false;
    counts = static_cast<int16_t>(value);
    return 1;
}

}  // namespace drv
