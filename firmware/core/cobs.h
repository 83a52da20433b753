// COBS (Consistent Overhead Byte Stuffing), the variant of the Python `cobs` package
// the host uses: a code byte c < 0xFF means c-1 data bytes then a zero (the zero after
// the last group is implicit); c == 0xFF means 254 data bytes and no zero.
// Contract: cobs_encode writes at most n + n/254 + 1 bytes, none of them 0x00, and no
// delimiter. cobs_decode returns the decoded length or -1 when the input contains 0x00,
// a code points past the end, or the output would exceed out_cap. Decoding in place
// (out == in) is allowed: the output never overtakes the input.
#pragma once
#include <stdint.h>

namespace fw {

uint16_t cobs_encode(const uint8_t* in, uint16_t n, uint8_t* out);
int16_t cobs_decode(const uint8_t* in, uint16_t n, uint8_t* out, uint16_t out_cap);

}  // namespace fw
