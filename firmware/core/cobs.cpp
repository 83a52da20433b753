#include "cobs.h"

namespace fw {

uint16_t cobs_encode(const uint8_t* in, uint16_t n, uint8_t* out) {
    uint16_t code_at = 0;  // where the current group's code byte goes
    uint16_t o = 1;
    uint8_t code = 1;
    bool after_full = false;  // the last group was a full 0xFF group
    for (uint16_t i = 0; i < n; ++i) {
        after_full = false;
        if (in[i] == 0) {
            out[code_at] = code;
            code_at = o++;
            code = 1;
            continue;
        }
        out[o++] = in[i];
        if (++code == 0xFF) {
            out[code_at] = code;
            code_at = o++;
            code = 1;
            after_full = true;
        }
    }
    // Input ending exactly on a full group needs no trailing code (as the host encodes).
    if (after_full) return static_cast<uint16_t>(o - 1);
    out[code_at] = code;
    return o;
}

int16_t cobs_decode(const uint8_t* in, uint16_t n, uint8_t* out, uint16_t out_cap) {
    uint16_t i = 0, o = 0;
    while (i < n) {
        uint8_t code = in[i++];
        if (code == 0) return -1;
        for (uint8_t k = 1; k < code; ++k) {
            if (i >= n || in[i] == 0 || o >= out_cap) return -1;
            out[o++] = in[i++];
        }
        if (i < n && code != 0xFF) {
            if (o >= out_cap) return -1;
            out[o++] = 0;
        }
    }
    return static_cast<int16_t>(o);
}

}  // namespace fw
