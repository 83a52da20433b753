// Every pin of the bench on the Arduino Mega 2560 (ATmega2560), in one place.
//
// Contract. AVR only (included by hal/*.cpp). Each logical pin of hal/gpio.h maps to a
// port and bit here; the step ISR uses the STEP/DIR macros directly. Peripheral pins
// that the hardware fixes (UART0, TWI, OC2A) are listed too, so the wiring is readable
// from this file alone.
//
//   Function                         AVR pin  Mega header  Notes
//   UART0 RXD0 (USB serial)          PE0      D0           250000 baud, U2X
//   UART0 TXD0                       PE1      D1
//   A4988 STEP                       PA0      D22          pulse >= 1 us, low >= 1 us; 10k pull-down
//   A4988 DIR                        PA1      D23          set >= 200 ns before STEP rises
//   A4988 /ENABLE                    PA2      D24          active low; 10k pull-DOWN: energized through reset
//   A4988 MS1                        PA3      D25          MS1=MS2=MS3=1 -> 1/16 step
//   A4988 MS2                        PA4      D26
//   A4988 MS3                        PA5      D27
//   CS5513 /CS                       PC0      D37          bit-banged 3-wire port
//   CS5513 SCLK                      PC1      D36
//   CS5513 SDO                       PC2      D35          input, pull-up (absent ADC = never ready)
//   AD8276 current source enable     PC3      D34          active high (50 mA through the strings)
//   Heater MOSFET gate               PB4      D10          OC2A, Timer2 fast PWM
//   TWI SDA (ADS1115)                PD1      D20          400 kHz, external pull-ups on the board
//   TWI SCL (ADS1115)                PD0      D21
//   ADS1115 ALERT/RDY                PE4      D2           INT4, falling edge; open drain: 10k pull-up to 5 V
//                                                          on the board (~8 us low pulse per conversion)
//   Status LED                       PB7      D13          on-board LED "L"
//
// Timers: Timer1 = step generator (CTC, F_CPU/8); Timer2 = heater PWM; Timer3 = the
// microsecond clock (normal mode, F_CPU/8, overflow ISR). Timer0/4/5 are unused.
#pragma once
#include <avr/io.h>

#define PINS_STEP_PORT PORTA
#define PINS_STEP_BIT 0
#define PINS_DIR_PORT PORTA
#define PINS_DIR_BIT 1
// Used before main() and in the watchdog ISR, where the gpio helpers are not available.
#define PINS_EN_PIN PINA
#define PINS_EN_BIT 2
#define PINS_ISRC_PORT PORTC
#define PINS_ISRC_BIT 3
// The CS5513 word is shifted in with direct port access (gpio.cpp: res_shift_in).
#define PINS_RES_SCLK_PORT PORTC
#define PINS_RES_SCLK_BIT 1
#define PINS_RES_SDO_PIN PINC
#define PINS_RES_SDO_BIT 2

// ADS1115 ALERT/RDY: external interrupt INT4 (EICRB ISC4[1:0] = 10, falling edge).
#define PINS_ADS_RDY_PIN PINE
#define PINS_ADS_RDY_BIT 4

// X-macro: (hal::Pin, port letter, bit). The order need not match the enum; gpio.cpp
// expands it into switch statements with constant addresses (sbi/cbi where possible),
// so no pin table occupies SRAM.
#define HAL_PIN_TABLE(X)      \
    X(PIN_MOTOR_STEP, A, 0)   \
    X(PIN_MOTOR_DIR, A, 1)    \
    X(PIN_MOTOR_EN, A, 2)     \
    X(PIN_MOTOR_MS1, A, 3)    \
    X(PIN_MOTOR_MS2, A, 4)    \
    X(PIN_MOTOR_MS3, A, 5)    \
    X(PIN_RES_CS, C, 0)       \
    X(PIN_RES_SCLK, C, 1)     \
    X(PIN_RES_SDO, C, 2)      \
    X(PIN_ISRC_EN, C, 3)      \
    X(PIN_HEATER, B, 4)       \
    X(PIN_LED, B, 7)
