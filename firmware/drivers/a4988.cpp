#include "a4988.h"

#include "../hal/gpio.h"

namespace drv {
namespace a4988 {

namespace {
bool g_enabled = false;
}

void init(bool keep_enabled) {
    hal::gpio_output(hal::PIN_MOTOR_STEP, false);  // no edge can reach the driver from here on
    hal::gpio_output(hal::PIN_MOTOR_EN, !keep_enabled);
    hal::gpio_output(hal::PIN_MOTOR_DIR, false);
    hal::gpio_output(hal::PIN_MOTOR_MS1, true);
    hal::gpio_output(hal::PIN_MOTOR_MS2, true);
    hal::gpio_output(hal::PIN_MOTOR_MS3, true);
    g_enabled = keep_enabled;
}

void enable(bool on) {
    hal::gpio_write(hal::PIN_MOTOR_EN, !on);
    g_enabled = on;
}

bool enabled() { return g_enabled; }

void set_direction(int8_t direction) { hal::gpio_write(hal::PIN_MOTOR_DIR, dir_level(direction)); }

}  // namespace a4988
}  // namespace drv
