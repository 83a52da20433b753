// Power stages: the A4988 (STEP/DIR//ENABLE), the AD8276 sense-current enable and the
// heater MOSFET gate, with the board's pull resistors.
//
// Contract. Counts a step on each STEP rising edge while the driver is enabled (DIR
// high = +1), and flags what the real driver would not accept: STEP high or low shorter
// than 1 us, DIR changed within 200 ns before or after a rising edge. Wiring (wiring.c):
// STEP, the heater gate and the source enable have pull-downs; /ENABLE a pull-down
// (recommended: the driver stays energized through a reset) or, with --enable-pull up,
// a pull-up (the motor is released whenever the AVR resets). While the driver is
// disabled a loaded, twisted TSA turns the motor back towards zero twist at
// --backdrive-steps-per-s (counted: steps.backdriven), so a position kept across such
// a reset would be wrong. The heater duty is read from Timer2 (OC2A fast PWM, on for
// (OCR2A + 1)/256 of a period) or the port bit when the compare output is disconnected;
// the plant is given its 8 ms moving average (the firmware dithers the duty period by
// period), and each stretch of heating (no off time longer than 3 PWM periods) is kept
// with its mean duty for the summary. Driving the heater while the sense current is on
// is an interlock violation (the firmware must never do it).
#include <math.h>
#include <string.h>

#include <avr_ioport.h>

#include "harness.h"
#include "rig_map.h"

#define PWM_PERIOD_CYCLES 16384  // Timer2 at F_CPU/64, 256 counts
#define HEATER_EMA_S 0.008

static struct harness *g_h;
static struct {
    double duty;             // instantaneous
    uint64_t since;          // cycle of the last duty change
    double ema;              // the plant's view
    uint64_t last_nonzero;   // last cycle the duty was > 0
    int on;                  // inside a stretch of heating
    uint64_t on_start;
    double on_integral;      // duty x cycles since on_start
    uint64_t backdrive_last;
    double backdrive_frac;
} g;

static uint64_t ns_to_cycles(uint64_t ns) { return (ns * 16 + 999) / 1000; }

static double duty_now(const struct harness *h) {
    const uint8_t *d = h->avr->data;
    if (d[REG_TCCR2A] & (1 << TCCR2A_COM2A1)) return (d[REG_OCR2A] + 1) / 256.0;
    return wiring_level(h, RIG_HEATER_PORT, RIG_HEATER_BIT) ? 1.0 : 0.0;
}

// Account the duty held since the last change, up to now.
static void heater_update(struct harness *h) {
    const uint64_t now = h->avr->cycle;
    const uint64_t dt = now - g.since;
    if (dt) {
        g.ema += (g.duty - g.ema) * (1.0 - exp(-(double)dt / (HEATER_EMA_S * HZ_CPU)));
        if (g.on) g.on_integral += g.duty * (double)dt;
    }
    g.since = now;
    const double d = duty_now(h);
    if (d > 0) {
        g.last_nonzero = now;
        if (!g.on) {
            g.on = 1;
            g.on_start = now;
            g.on_integral = 0;
        }
    } else if (g.on && now - g.last_nonzero > 3 * PWM_PERIOD_CYCLES) {
        // off for good: the stretch ended when the duty last fell to 0
        const uint64_t end = g.last_nonzero;
        const double span = (double)(end - g.on_start);
        if (h->heater_periods < HEATER_MAX_PERIODS) {
            h->heater_period_start_s[h->heater_periods] = (double)g.on_start / HZ_CPU;
            h->heater_period_end_s[h->heater_periods] = (double)end / HZ_CPU;
            h->heater_period_duty[h->heater_periods] = span > 0 ? g.on_integral / span : 0;
        }
        h->heater_periods++;
        h->heater_last_off_s = (double)end / HZ_CPU;
        g.on = 0;
    }
    g.duty = d;
}

double harness_heater_duty(const struct harness *h) {
    heater_update((struct harness *)h);
    return g.ema;
}

// Counted once per episode: entering the state "heater driven and sense current on".
void drive_check_interlock(struct harness *h) {
    heater_update(h);
    const int bad = h->drive.sense_on && g.duty > 0;
    if (bad && !h->drive.interlock_active) h->drive.interlock_violations++;
    h->drive.interlock_active = bad;
}

static void on_step(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    struct harness *h = param;
    struct drive_state *s = &h->drive;
    const uint64_t now = h->avr->cycle;
    const int level = value & 1;
    if (level == s->step_level) return;
    s->step_level = level;
    if (level) {
        if (s->last_step_fall) {
            const uint64_t low = now - s->last_step_fall;
            if (!s->min_step_low_cycles || low < s->min_step_low_cycles) s->min_step_low_cycles = low;
            if (low < ns_to_cycles(A4988_MIN_PULSE_NS)) s->pulse_width_violations++;
        }
        if (s->last_dir_change && now - s->last_dir_change < ns_to_cycles(A4988_DIR_SETUP_NS))
            s->dir_setup_violations++;
        s->last_step_rise = now;
        if (s->enabled) {
            s->steps += s->dir_level ? 1 : -1;
            s->steps_total++;
            s->last_step_cycle = now;
        } else {
            s->steps_while_disabled++;
        }
    } else {
        const uint64_t high = now - s->last_step_rise;
        if (!s->min_step_high_cycles || high < s->min_step_high_cycles) s->min_step_high_cycles = high;
        if (high < ns_to_cycles(A4988_MIN_PULSE_NS)) s->pulse_width_violations++;
        s->last_step_fall = now;
    }
}

static void on_dir(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    struct harness *h = param;
    struct drive_state *s = &h->drive;
    const int level = value & 1;
    if (level == s->dir_level) return;
    s->dir_level = level;
    s->last_dir_change = h->avr->cycle;
    if (s->step_level && s->last_step_rise &&
        h->avr->cycle - s->last_step_rise < ns_to_cycles(A4988_DIR_HOLD_NS))
        s->dir_hold_violations++;
}

static void on_enable(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    struct harness *h = param;
    const int enabled = !(value & 1);  // /ENABLE is active low
    if (h->drive.enabled && !enabled) {
        h->drive.last_disable_cycle = h->avr->cycle;
        h->drive.disables++;
        g.backdrive_last = h->avr->cycle;
        g.backdrive_frac = 0;
    }
    h->drive.enabled = enabled;
}

static void on_sense(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    struct harness *h = param;
    const int on = value & 1;
    if (on && !h->drive.sense_on) h->drive.sense_on_cycle = h->avr->cycle;
    if (!on && h->drive.sense_on) h->drive.last_sense_off_cycle = h->avr->cycle;
    h->drive.sense_on = on;
    drive_check_interlock(h);
}

static void on_heater_pin(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    (void)value;
    drive_check_interlock(param);
}

static void on_heater_reg(struct avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param) {
    (void)avr;
    (void)addr;
    (void)v;
    drive_check_interlock(param);
}

// Called every slice: a disabled driver lets the loaded strings turn the motor back.
void drive_tick(struct harness *h) {
    struct drive_state *s = &h->drive;
    const uint64_t now = h->avr->cycle;
    if (s->enabled || h->backdrive_steps_per_s <= 0 || s->steps == 0) {
        g.backdrive_last = now;
        g.backdrive_frac = 0;
        return;
    }
    g.backdrive_frac += (double)(now - g.backdrive_last) / HZ_CPU * h->backdrive_steps_per_s;
    g.backdrive_last = now;
    while (g.backdrive_frac >= 1.0 && s->steps != 0) {
        s->steps += s->steps > 0 ? -1 : 1;
        s->steps_backdriven++;
        g.backdrive_frac -= 1.0;
    }
}

int harness_motor_moving(const struct harness *h) {
    const struct drive_state *s = &h->drive;
    return s->steps_total && h->avr->cycle - s->last_step_cycle < h->moving_window_cycles;
}

static void watch(struct harness *h, char port, int bit, avr_irq_notify_t fn) {
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_IOPORT_GETIRQ(port), bit), fn, h);
}

void drive_attach(struct harness *h, int enable_pull_up) {
    g_h = h;
    memset(&g, 0, sizeof g);
    memset(&h->drive, 0, sizeof h->drive);
    watch(h, RIG_STEP_PORT, RIG_STEP_BIT, on_step);
    watch(h, RIG_DIR_PORT, RIG_DIR_BIT, on_dir);
    watch(h, RIG_EN_PORT, RIG_EN_BIT, on_enable);
    watch(h, RIG_ISRC_EN_PORT, RIG_ISRC_EN_BIT, on_sense);
    watch(h, RIG_HEATER_PORT, RIG_HEATER_BIT, on_heater_pin);
    avr_register_io_write(h->avr, REG_OCR2A, on_heater_reg, h);
    avr_register_io_write(h->avr, REG_TCCR2A, on_heater_reg, h);
    wiring_pull(h, RIG_STEP_PORT, RIG_STEP_BIT, 0);
    wiring_pull(h, RIG_HEATER_PORT, RIG_HEATER_BIT, 0);
    wiring_pull(h, RIG_ISRC_EN_PORT, RIG_ISRC_EN_BIT, 0);
    wiring_pull(h, RIG_EN_PORT, RIG_EN_BIT, enable_pull_up ? 1 : 0);
    h->drive.enabled = !enable_pull_up;
}

// The AVR reset: Timer2 and the ports are back at their reset values.
void drive_reset(struct harness *h) { drive_check_interlock(h); }
