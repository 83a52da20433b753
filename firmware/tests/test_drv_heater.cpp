// Heater duty (V / V_supply)^2 on 4096 dithered steps, the voltage applied, clamping, and
// the sense-current interlock.
#include "../config.h"
#include "../drivers/current_source.h"
#include "../drivers/heater.h"
#include "../drivers/heater_dither.h"
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
    // n = round(4096 V^2 / 24^2): the 8-bit (OCR + 1)/256 scale dithered 16 ways.
    CHECK_EQ(drv::heater::steps_for_mV(0), 0);
    CHECK_EQ(drv::heater::steps_for_mV(200), 0);      // 0.28 -> off
    CHECK_EQ(drv::heater::steps_for_mV(300), 1);      // 0.64 -> the smallest step, 375 mV
    CHECK_EQ(drv::heater::steps_for_mV(1000), 7);     // 7.11
    CHECK_EQ(drv::heater::steps_for_mV(2000), 28);    // 28.44
    CHECK_EQ(drv::heater::steps_for_mV(3000), 64);    // exact
    CHECK_EQ(drv::heater::steps_for_mV(12000), 1024);  // exact
    CHECK_EQ(drv::heater::mV_for_steps(1), 375);
    CHECK_EQ(drv::heater::mV_for_steps(7), 992);
    CHECK_EQ(drv::heater::mV_for_steps(28), 1984);
    CHECK_EQ(drv::heater::mV_for_steps(4096), 24000);
}

TEST(drv_heater_applied_voltage_within_one_percent_from_2_V) {
    // The old 8-bit duty applied 2.12 V for 2 V (+12 % power) and nothing for 1 V.
    double worst = 0;
    for (uint16_t mV = 2000; mV <= cfg::MAX_HEATER_MV; ++mV) {
        const uint16_t applied = drv::heater::mV_for_steps(drv::heater::steps_for_mV(mV));
        const double err = (applied > mV ? applied - mV : mV - applied) / static_cast<double>(mV);
        if (err > worst) worst = err;
    }
    CHECK(worst < 0.01);
    for (uint16_t mV = 300; mV < 2000; ++mV) CHECK(drv::heater::mV_for_steps(drv::heater::steps_for_mV(mV)) > 0);
    // The applied voltage is the nearest step in power (V^2), never beyond half a step.
    for (uint16_t mV = 0; mV <= cfg::MAX_HEATER_MV; mV += 7) {
        const uint16_t n = drv::heater::steps_for_mV(mV);
        const double v2 = static_cast<double>(mV) * mV, step = drv::heater::STEP_MV2;
        CHECK(v2 >= (n - 0.5) * step - 1e-6 && v2 <= (n + 0.5) * step + 1e-6);
    }
}

TEST(drv_heater_dither_gives_exact_duty_over_16_periods) {
    for (uint16_t steps = 0; steps <= drv::HEATER_DUTY_STEPS; ++steps) {
        drv::HeaterDither d;
        d.set(steps);
        uint32_t on = 0;
        for (int period = 0; period < 16; ++period) {
            const uint16_t n = d.next();
            CHECK(n == steps / 16 || n == steps / 16 + 1);
            CHECK(n <= 256);
            on += n;
        }
        CHECK_EQ(on, steps);
        CHECK_EQ(d.acc, 0);
    }
}

TEST(drv_heater_clamps_at_max) {
    setup();
    CHECK_EQ(drv::heater::steps_for_mV(24000), drv::heater::steps_for_mV(cfg::MAX_HEATER_MV));
    CHECK_EQ(drv::heater::set_mV(30000), cfg::MAX_HEATER_MV);
    CHECK_EQ(fake::heater_steps(), 1024);
    CHECK_EQ(drv::heater::applied_mV(), cfg::MAX_HEATER_MV);
}

TEST(drv_heater_set_and_off) {
    setup();
    CHECK_EQ(drv::heater::set_mV(6000), 6000);
    CHECK_EQ(fake::heater_steps(), 256);
    CHECK(drv::heater::is_on());
    CHECK_EQ(drv::heater::set_mV(0), 0);
    CHECK_EQ(fake::heater_steps(), 0);
    CHECK(!drv::heater::is_on());
    CHECK_EQ(drv::heater::set_mV(200), 0);  // rounds to duty 0: reported as off
    CHECK(!drv::heater::is_on());
    CHECK_EQ(drv::heater::set_mV(2000), 1984);  // what is applied, not what was asked
    CHECK_EQ(drv::heater::applied_mV(), 1984);
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
