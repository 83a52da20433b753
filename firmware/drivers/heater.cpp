#include "heater.h"

#include "../hal/pwm.h"
#include "current_source.h"
#include "heater_dither.h"

namespace drv {
namespace heater {

namespace {
uint16_t g_steps = 0;
uint16_t g_mV = 0;
}  // namespace

void init() {
    hal::heater_pwm_init();
    hal::heater_pwm_set_steps(0);
    g_steps = 0;
    g_mV = 0;
}

uint16_t set_mV(uint16_t mV) {
    const uint16_t steps = steps_for_mV(mV);
    if (steps) current_source::force_off();
    hal::heater_pwm_set_steps(steps);
    g_steps = steps;
    g_mV = mV_for_steps(steps);
    return g_mV;
}

bool is_on() { return g_steps != 0; }

uint16_t applied_mV() { return g_mV; }

}  // namespace heater
}  // namespace drv
