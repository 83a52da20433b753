// ADS1115 16-bit ADC on I2C: single-shot conversions of AIN0 against GND.
//
// Contract. start() writes the config register once (OS=1 start, MUX=100 AIN0/GND,
// PGA = cfg::ADS1115_PGA_BITS, MODE=1 single-shot, DR = cfg::ADS1115_DR_BITS,
// comparator off: COMP_QUE=11) and returns false when the ADC does not ACK. poll() does
// no I2C traffic until the nominal conversion time (+10 % oscillator tolerance + 100 us)
// has passed; then it reads the config register and, once OS reads 1 (idle), the
// conversion register (big-endian, two's complement). 1 = counts valid, 0 = not yet,
// -1 = I2C failure or still busy CONVERSION_TIMEOUT_US after start. Each I2C exchange
// blocks ~60-100 us at 400 kHz (bounded by hal::TWI_TIMEOUT_US).
#pragma once
#include <stdint.h>

namespace drv {

class Ads1115 {
public:
    // Register pointer values (datasheet 9.6.1).
    static const uint8_t REG_CONVERSION = 0x00;
    static const uint8_t REG_CONFIG = 0x01;
    static const uint8_t REG_LO_THRESH = 0x02;
    static const uint8_t REG_HI_THRESH = 0x03;
    static const uint32_t CONVERSION_TIMEOUT_US = 250000UL;  // >> 1/8 SPS

    // Config word for one single-shot AIN0 conversion with the given PGA/DR bits.
    static uint16_t config_word(uint8_t pga_bits, uint8_t dr_bits);
    // Time to wait after start before the first poll of OS, for the DR bits.
    static uint32_t conversion_wait_us(uint8_t dr_bits);

    explicit Ads1115(uint8_t address7);
    bool start();
    int8_t poll(int16_t& counts);
    // Continuous mode: Lo_thresh MSB 0 and Hi_thresh MSB 1 turn ALERT/RDY into the
    // conversion-ready pulse (COMP_QUE = 00 keeps the pin enabled), then the config
    // (MODE = 0, the same MUX/PGA/DR) starts converting, and the pointer is left on
    // the conversion register so read_latest() is one 2-byte read. false: no ACK.
    bool start_continuous();
    // Back to single-shot, powered down, ALERT/RDY off (COMP_QUE = 11).
    bool stop_continuous();
    // The latest conversion (continuous mode); false on an I2C failure.
    bool read_latest(int16_t& counts);
    static uint16_t continuous_config_word(uint8_t pga_bits, uint8_t dr_bits);
    bool busy() const { return started_; }

private:
    bool read_register(uint8_t reg, uint16_t& value);
    bool write_register(uint8_t reg, uint16_t value);
    uint8_t address_;
    bool started_;
    uint32_t started_at_us_;
};

}  // namespace drv
