// Heater duty (V / V_supply)^2 on 8 bits, clamping, and the sense-current interlock.
#include "../config.h"
#include "../drivers/current_source.h"
#include "../drivers/heater.h"
#include "../hal/gpio.h"
#include "fake_hal.h"
#include "test_runner.h"

namespace {
void setup() {
    fake::reset();
    drv::heater::init();
    drv::current_source::init();
}
}  // namespace

TEST(drv_heater_duty_for_several_voltages) {
    static_assert(cfg::HEATER_SUPPLY_MV == 24000, "expected values assume a 24 V supply");
    CHECK_EQ(drv::heater::duty_for_mV(0), 0);
    CHECK_EQ(drv::heater::duty_for_mV(1000), 0);     // 255/576 = 0.44 -> 0
    CHECK_EQ(drv::heater::duty_for_mV(2000), 2);     // 1.77
    CHECK_EQ(drv::heater::duty_for_mV(3000), 4);     // 3.98
    CHECK_EQ(drv::heater::duty_for_mV(6000), 16);    // 15.94
    CHECK_EQ(drv::heater::duty_for_mV(10000), 44);   // 44.27
    CHECK_EQ(drv::heater::duty_for_mV(12000), 64);   // 63.75
}

TEST(drv_heater_clamps_at_max) {
    setup();
    CHECK_EQ(drv::heater::duty_for_mV(24000), drv::heater::duty_for_mV(cfg::MAX_HEATER_MV));
    CHECK_EQ(drv::heater::set_mV(30000), cfg::MAX_HEATER_MV);
    CHECK_EQ(fake::heater_duty(), 64);
    CHECK_EQ(drv::heater::applied_mV(), cfg::MAX_HEATER_MV);
}

TEST(drv_heater_set_and_off) {
    setup();
    CHECK_EQ(drv::heater::set_mV(6000), 6000);
    CHECK_EQ(fake::heater_duty(), 16);
    CHECK(drv::heater::is_on());
    CHECK_EQ(drv::heater::set_mV(0), 0);
    CHECK_EQ(fake::heater_duty(), 0);
    CHECK(!drv::heater::is_on());
    CHECK_EQ(drv::heater::set_mV(500), 0);  // rounds to duty 0: reported as off
    CHECK(!drv::heater::is_on());
}

TEST(drv_heater_on_forces_sense_current_off) {
    setup();
    CHECK(drv::current_source::set(true));
    CHECK(fake::level(hal::PIN_ISRC_EN));
    drv::heater::set_mV(5000);
    CHECK(!fake::level(hal::PIN_ISRC_EN));
    CHECK(!drv::current_source::on());
    // The source went off before the PWM came on: check event order.
    int off_at = -1;
    for (int i = 0; i < fake::pin_event_count(); ++i)
        if (fake::pin_event(i).pin == hal::PIN_ISRC_EN && !fake::pin_event(i).level) off_at = i;
    CHECK(off_at >= 0);
    CHECK_EQ(fake::heater_pwm_writes(), 2);  // init + set
}

TEST(drv_current_source_refused_while_heater_on) {
    setup();
    drv::heater::set_mV(8000);
    CHECK(!drv::current_source::set(true));
    CHECK(!fake::level(hal::PIN_ISRC_EN));
    CHECK(drv::current_source::set(false));
    drv::heater::set_mV(0);
    CHECK(drv::current_source::set(true));
    CHECK(fake::level(hal::PIN_ISRC_EN));
}

TEST(drv_current_source_records_enable_time) {
    setup();
    fake::advance_us(1234);
    CHECK(drv::current_source::set(true));
    CHECK_EQ(drv::current_source::enabled_at_us(), 1234);
    fake::advance_us(100);
    CHECK(drv::current_source::set(true));  // already on: time unchanged
    CHECK_EQ(drv::current_source::enabled_at_us(), 1234);
}
