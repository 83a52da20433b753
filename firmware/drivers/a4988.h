// A4988 stepper driver: enable, microstepping, and the pin levels the step ISR uses.
//
// Contract. init(keep_enabled) drives STEP low first, then /ENABLE: low (driver on) when
// keep_enabled - the motor stayed energized through the reset (a pull-down, or nothing,
// on /ENABLE: the A4988 runs with it open) and must not let go now - else high; then
// DIR low and MS1..MS3 high (1/16 microstep, cfg::STEPS_PER_TURN = 200 * 16).
// enable(true) drives /ENABLE low (active low). STEP and DIR are toggled by the step ISR (hal/step_timer.cpp)
// with direct port writes; dir_level() is the DIR level it uses for a direction, so the
// ISR and the tests agree on which way +1 turns. Timing the ISR honours (datasheet):
// STEP high >= 1 us, STEP low >= 1 us, DIR setup >= 200 ns before and hold >= 200 ns
// after the STEP rising edge.
#pragma once
#include <stdint.h>

namespace drv {
namespace a4988 {

static const uint16_t STEP_MIN_HIGH_NS = 1000;
static const uint16_t STEP_MIN_LOW_NS = 1000;
static const uint16_t DIR_SETUP_NS = 200;

// +1 (twist) = DIR high, -1 = DIR low.
inline bool dir_level(int8_t direction) { return direction > 0; }

void init(bool keep_enabled);
void enable(bool on);
bool enabled();
// Set DIR for the next step (outside the ISR path, e.g. for a manual jog in tests).
void set_direction(int8_t direction);

}  // namespace a4988
}  // namespace drv
