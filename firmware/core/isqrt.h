// Integer square root, 32-bit (no 64-bit arithmetic: a few hundred cycles on the AVR).
#pragma once
#include <stdint.h>

namespace fw {

// floor(sqrt(x)).
inline uint32_t isqrt32(uint32_t x) {
    uint32_t result = 0;
    uint32_t bit = 1UL << 30;
    while (bit > x) bit >>= 2;
    while (bit != 0) {
        if (x >= result + bit) {
            x -= result + bit;
            result = (result >> 1) + bit;
        } else {
            result >>= 1;
        }
        bit >>= 2;
    }
    return result;
}

}  // namespace fw
