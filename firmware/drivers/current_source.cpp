#include "current_source.h"

#include "../hal/clock.h"
#include "../hal/gpio.h"
#include "heater.h"

namespace drv {
namespace current_source {

namespace {
bool g_on = false;
uint64_t g_enabled_at_us = 0;
}  // namespace

void init() {
    hal::gpio_output(hal::PIN_ISRC_EN, false);
    g_on = false;
}

bool set(bool want_on) {
    if (!want_on) {
        force_off();
        return true;
    }
    if (heater::is_on()) return false;
    if (!g_on) {
        hal::gpio_write(hal::PIN_ISRC_EN, true);
        g_on = true;
        g_enabled_at_us = hal::micros();
    }
    return true;
}

void force_off() {
    hal::gpio_write(hal::PIN_ISRC_EN, false);
    g_on = false;
}

bool on() { return g_on; }

uint64_t enabled_at_us() { return g_enabled_at_us; }

}  // namespace current_source
}  // namespace drv
