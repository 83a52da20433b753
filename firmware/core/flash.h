// Constant tables in flash on the AVR, ordinary constants elsewhere.
//
// Contract. Declare a table `static const T NAME[N] FW_FLASH = {...};` and read an
// element with flash_u8 / flash_u16 (the AVR's program memory is a separate address
// space, read with LPM; the native build reads plain memory). Tables must sit in the
// first 64 KB of flash (avr-gcc puts .progmem right after the vectors).
#pragma once
#include <stdint.h>

#ifdef __AVR__
#include <avr/pgmspace.h>
#define FW_FLASH PROGMEM
namespace fw {
inline uint8_t flash_u8(const uint8_t* p) { return pgm_read_byte(p); }
inline uint16_t flash_u16(const uint16_t* p) { return pgm_read_word(p); }
}  // namespace fw
#else
#define FW_FLASH
namespace fw {
inline uint8_t flash_u8(const uint8_t* p) { return *p; }
inline uint16_t flash_u16(const uint16_t* p) { return *p; }
}  // namespace fw
#endif
