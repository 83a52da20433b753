// Heater PWM dither: 4096 duty steps out of an 8-bit timer (used by the Timer2 ISR).
//
// Contract. Timer2's fast PWM keeps the gate on for n/256 of each ~1.02 ms period,
// n = OCR2A + 1 in 1..256 with the output connected, n = 0 with it disconnected. A
// duty of `steps`/4096 (0..4096) is made by giving 16 consecutive periods n =
// steps/16 or steps/16 + 1, the remainder spread by an accumulator: over every 16
// periods (16.4 ms, far shorter than the strings' thermal time constant) the gate is
// on exactly steps/4096 of the time. set() splits the duty outside the ISR; next()
// returns the next period's n with a few byte operations (no shift loops in the ISR).
// Header-only so the ISR inlines it; tested natively.
#pragma once
#include <stdint.h>

namespace drv {

static const uint16_t HEATER_DUTY_STEPS = 4096;

struct HeaterDither {
    uint16_t base;  // steps / 16: every period's on-count, 0..256
    uint8_t frac;   // steps % 16: periods out of 16 that get one more
    uint8_t acc;    // remainder accumulated over the periods, 0..15

    void set(uint16_t steps) {
        base = static_cast<uint16_t>(steps >> 4);
        frac = static_cast<uint8_t>(steps & 0xF);
        acc = 0;
    }
    uint16_t next() {
        uint16_t n = base;
        acc = static_cast<uint8_t>(acc + frac);
        if (acc >= 16) {
            acc = static_cast<uint8_t>(acc - 16);
            ++n;
        }
        return n;
    }
};

}  // namespace drv
