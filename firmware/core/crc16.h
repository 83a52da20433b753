// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final XOR).
// Contract: crc16("123456789") == 0x29B1. Table-free byte update (a few shifts and
// XORs per byte; avr-libc's assembly version on the AVR): no flash or RAM table.
#pragma once
#include <stdint.h>
#ifdef __AVR__
#include <util/crc16.h>  // _crc_xmodem_update: the same polynomial, hand-written assembly
#endif

namespace fw {

static const uint16_t CRC16_INIT = 0xFFFF;

inline uint16_t crc16_update(uint16_t crc, uint8_t byte) {
#ifdef __AVR__
    return _crc_xmodem_update(crc, byte);  // MSB-first 0x1021, any initial value
#else
    // x is the top byte folded with the data; the polynomial 0x1021 = x^12 + x^5 + 1
    // becomes three shifted copies of x (plus x >> 4 folded in for the x^12 term).
    uint8_t x = static_cast<uint8_t>((crc >> 8) ^ byte);
    x ^= static_cast<uint8_t>(x >> 4);
    return static_cast<uint16_t>((crc << 8) ^ (static_cast<uint16_t>(x) << 12) ^
                                 (static_cast<uint16_t>(x) << 5) ^ x);
#endif
}

uint16_t crc16(const uint8_t* data, uint16_t n, uint16_t crc = CRC16_INIT);

}  // namespace fw
