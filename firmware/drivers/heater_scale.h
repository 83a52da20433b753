// The heater's duty scale: requested voltage -> duty steps -> voltage applied.
//
// Contract. Pure integer functions (header-only: the native fake board uses them too).
// duty = n / HEATER_DUTY_STEPS with n = round(4096 V^2 / V_s^2), V clamped to
// cfg::MAX_HEATER_MV and V_s; the voltage applied is round(V_s sqrt(n / 4096)) mV.
// See heater.h for the rounding rule and hal/pwm.h for how the duty is produced.
#pragma once
#include <stdint.h>

#include "../config.h"
#include "../core/isqrt.h"
#include "heater_dither.h"

namespace drv {
namespace heater {

// V_s^2 / 4096 exactly: the duty step in mV^2.
static const uint32_t STEP_MV2 =
    static_cast<uint32_t>(cfg::HEATER_SUPPLY_MV) * cfg::HEATER_SUPPLY_MV / HEATER_DUTY_STEPS;
static_assert(cfg::HEATER_SUPPLY_MV % 64 == 0, "V_s^2 / 4096 must be exact");

inline uint16_t clamp_mV(uint16_t mV) {
    if (mV > cfg::MAX_HEATER_MV) mV = cfg::MAX_HEATER_MV;
    if (mV > cfg::HEATER_SUPPLY_MV) mV = cfg::HEATER_SUPPLY_MV;
    return mV;
}

inline uint16_t steps_for_mV(uint16_t mV) {
    mV = clamp_mV(mV);
    const uint32_t v2 = static_cast<uint32_t>(mV) * mV;
    const uint32_t n = (v2 + STEP_MV2 / 2) / STEP_MV2;
    return static_cast<uint16_t>(n > HEATER_DUTY_STEPS ? HEATER_DUTY_STEPS : n);
}

inline uint16_t mV_for_steps(uint16_t steps) {
    // round(sqrt(x)): the root r rounds up when x - r^2 > r.
    const uint32_t x = static_cast<uint32_t>(steps) * STEP_MV2;
    uint32_t r = fw::isqrt32(x);
    if (x - r * r > r) ++r;
    return static_cast<uint16_t>(r);
}

// The equivalent voltage a request actually gets.
inline uint16_t applied_for_mV(uint16_t mV) { return mV_for_steps(steps_for_mV(mV)); }

}  // namespace heater
}  // namespace drv
