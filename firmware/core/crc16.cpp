#include "crc16.h"

namespace fw {

uint16_t crc16(const uint8_t* data, uint16_t n, uint16_t crc) {
    for (uint16_t i = 0; i < n; ++i) crc = crc16_update(crc, data[i]);
    return crc;
}

}  // namespace fw
