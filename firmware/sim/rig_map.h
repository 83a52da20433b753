// The rig's wiring and the ATmega2560 registers the harness reads, in one place.
//
// Contract. Mirrors firmware/hal/pins.h (tests/firmware/test_simavr_harness.py checks
// the two agree); register addresses are data-space addresses from the ATmega2560
// data sheet (register summary), used where simavr offers no IRQ to watch.
#pragma once

// (port letter, bit)
#define RIG_STEP_PORT 'A'
#define RIG_STEP_BIT 0
#define RIG_DIR_PORT 'A'
#define RIG_DIR_BIT 1
#define RIG_EN_PORT 'A'
#define RIG_EN_BIT 2
#define RIG_RES_CS_PORT 'C'
#define RIG_RES_CS_BIT 0
#define RIG_RES_SCLK_PORT 'C'
#define RIG_RES_SCLK_BIT 1
#define RIG_RES_SDO_PORT 'C'
#define RIG_RES_SDO_BIT 2
#define RIG_ISRC_EN_PORT 'C'
#define RIG_ISRC_EN_BIT 3
#define RIG_HEATER_PORT 'B'
#define RIG_HEATER_BIT 4
// TWI (fixed by the ATmega2560): SCL = PD0, SDA = PD1
#define RIG_SCL_PORT 'D'
#define RIG_SCL_BIT 0
#define RIG_SDA_PORT 'D'
#define RIG_SDA_BIT 1

// ADS1115 ALERT/RDY (open drain, the board's pull-up) on INT4, as PINS_ADS_RDY_* in hal/pins.h.
#define RIG_ADS_RDY_PORT 'E'
#define RIG_ADS_RDY_BIT 4
// Its conversion-ready pulse: ~8 us low (data sheet SBAS444, 9.3.8), in cycles at 16 MHz.
#define ADS1115_RDY_PULSE_CYCLES 128

// ADS1115 7-bit I2C address (ADDR pin to GND), as firmware/config.h ADS1115_ADDRESS.
#define RIG_ADS1115_ADDRESS 0x48

// Timer2 drives the heater gate (OC2A = PB4) in fast PWM.
#define REG_PORTB 0x25
#define REG_TCCR2A 0xB0
#define REG_OCR2A 0xB3
#define TCCR2A_COM2A1 7
#define REG_TIMSK2 0x70
#define TIMSK2_OCIE2A 1

// TWI: bit rate, status (prescaler in bits 1:0), control.
#define REG_TWBR 0xB8
#define REG_TWSR 0xB9
#define REG_TWCR 0xBC
#define TWCR_TWEN 2
#define TWCR_TWSTO 4
#define TWCR_TWSTA 5

// UART0 status (DOR0 = bit 3, FE0 = bit 4) and data; MCUSR; Timer3 control B.
#define REG_UCSR0A 0xC0
#define REG_UDR0 0xC6
#define UCSR0A_DOR0 3
#define REG_MCUSR 0x54
#define MCUSR_PORF 0
#define MCUSR_EXTRF 1
#define MCUSR_BORF 2
#define MCUSR_WDRF 3
#define REG_TCCR3B 0x91

// CS5513 serial port: SCLK high and low >= 250 ns (4 cycles at 16 MHz).
#define CS5513_MIN_SCLK_CYCLES 4

// A4988 timing (data sheet, electrical characteristics).
#define A4988_MIN_PULSE_NS 1000
#define A4988_DIR_SETUP_NS 200
#define A4988_DIR_HOLD_NS 200
