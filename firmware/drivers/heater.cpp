#include "heater.h"

#include "../config.h"
#include "../hal/pwm.h"
#include "current_source.h"

namespace drv {
namespace heater {

namespace {
// duty = (255 * V^2 + S^2 / 2) / S^2 with V^2 / 16 and S^2 / 16 keeps it in 32 bits.
const uint32_t SUPPLY_SQ_16 = (static_cast<uint32_t>(cfg::HEATER_SUPPLY_MV) * cfg::HEATER_SUPPLY_MV) / 16;
static_assert(cfg::MAX_HEATER_MV <= 16000, "255 * (V^2 / 16) must fit in 32 bits");
static_assert(cfg::HEATER_SUPPLY_MV % 4 == 0, "S^2 / 16 must be exact");

uint8_t g_duty = 0;
uint16_t g_mV = 0;

uint16_t clamp(uint16_t mV) {
    if (mV > cfg::MAX_HEATER_MV) mV = cfg::MAX_HEATER_MV;
    if (mV > cfg::HEATER_SUPPLY_MV) mV = cfg::HEATER_SUPPLY_MV;
    return mV;
}
}  // namespace

void init() {
    hal::heater_pwm_init();
    hal::heater_pwm_set(0);
    g_duty = 0;
    g_mV = 0;
}

uint8_t duty_for_mV(uint16_t mV) {
    mV = clamp(mV);
    const uint32_t v_sq_16 = (static_cast<uint32_t>(mV) * mV) / 16;
    const uint32_t duty = (255UL * v_sq_16 + SUPPLY_SQ_16 / 2) / SUPPLY_SQ_16;
    return static_cast<uint8_t>(duty > 255 ? 255 : duty);
}

uint16_t set_mV(uint16_t mV) {
    mV = clamp(mV);
    const uint8_t duty = duty_for_mV(mV);
    if (duty) current_source::force_off();
    hal::heater_pwm_set(duty);
    g_duty = duty;
    g_mV = duty ? mV : 0;
    return g_mV;
}

bool is_on() { return g_duty != 0; }

uint16_t applied_mV() { return g_mV; }

}  // namespace heater
}  // namespace drv
