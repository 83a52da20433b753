// A4988 driver: pin states after init, enable polarity, direction levels.
#include "../drivers/a4988.h"
#include "../hal/gpio.h"
#include "fake_hal.h"
#include "test_runner.h"

TEST(drv_a4988_init_disabled_sixteenth_step) {
    fake::reset();
    drv::a4988::init(false);
    CHECK(fake::is_output(hal::PIN_MOTOR_EN));
    CHECK(fake::level(hal::PIN_MOTOR_EN));  // /ENABLE high = outputs off
    CHECK(!fake::level(hal::PIN_MOTOR_STEP));
    CHECK(fake::level(hal::PIN_MOTOR_MS1));
    CHECK(fake::level(hal::PIN_MOTOR_MS2));
    CHECK(fake::level(hal::PIN_MOTOR_MS3));
    CHECK(!drv::a4988::enabled());
    // STEP is driven low before /ENABLE, before any other motor pin is touched.
    CHECK(fake::pin_event_count() > 1);
    CHECK_EQ(fake::pin_event(0).pin, hal::PIN_MOTOR_STEP);
    CHECK(!fake::pin_event(0).level);
    CHECK_EQ(fake::pin_event(1).pin, hal::PIN_MOTOR_EN);
    CHECK(fake::pin_event(1).level);
}

TEST(drv_a4988_init_keeps_a_held_motor_energized) {
    // /ENABLE read low at reset (pull-down): the driver never lets go of the motor.
    fake::reset();
    drv::a4988::init(true);
    CHECK(drv::a4988::enabled());
    for (int i = 0; i < fake::pin_event_count(); ++i) {
        if (fake::pin_event(i).pin == hal::PIN_MOTOR_EN) CHECK(!fake::pin_event(i).level);
    }
}

TEST(drv_a4988_enable_is_active_low) {
    fake::reset();
    drv::a4988::init(false);
    drv::a4988::enable(true);
    CHECK(!fake::level(hal::PIN_MOTOR_EN));
    CHECK(drv::a4988::enabled());
    drv::a4988::enable(false);
    CHECK(fake::level(hal::PIN_MOTOR_EN));
    CHECK(!drv::a4988::enabled());
}

TEST(drv_a4988_direction_levels) {
    fake::reset();
    drv::a4988::init(false);
    CHECK(drv::a4988::dir_level(1));
    CHECK(!drv::a4988::dir_level(-1));
    drv::a4988::set_direction(1);
    CHECK(fake::level(hal::PIN_MOTOR_DIR));
    drv::a4988::set_direction(-1);
    CHECK(!fake::level(hal::PIN_MOTOR_DIR));
}

TEST(drv_a4988_timing_constants_match_datasheet) {
    CHECK(drv::a4988::STEP_MIN_HIGH_NS >= 1000);
    CHECK(drv::a4988::STEP_MIN_LOW_NS >= 1000);
    CHECK(drv::a4988::DIR_SETUP_NS >= 200);
}
