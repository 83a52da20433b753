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
// a reset would be wrong. The heater gate is followed period by period, as the pin
// would be: at each BOTTOM of Timer2's fast PWM, with OC2A connected, the gate is on for
// (OCR2A + 1) timer ticks (the output latch sets at BOTTOM and clears at the compare
// match), with OC2A disconnected it follows PORTB4; disconnecting before the compare
// cuts the pulse short. From these on-times come the duty the plant is given (an 8 ms
// moving average: the firmware dithers the duty from period to period) and, for the
// summary, each stretch of heating (from the PWM starting until it stops: the compare
// interrupt enabled, OC2A connected or the pin high) with its mean duty. Driving the
// heater while the sense current is on is an interlock violation.
//
// simavr 1.6 trap: it applies an OCR2A write in fast PWM at once (and, when the new
// compare point lies later in the running period, fires a second compare match in that
// period), where the chip double-buffers OCR2A to the next BOTTOM (data sheet 18.7.3).
// The firmware writes OCR2A from the compare ISR, so without the buffer its dither ran
// two steps in some periods. The harness holds OCR2A writes made in fast PWM and hands
// them to simavr's timer one cycle before the next overflow.
#include <math.h>
#include <string.h>

#include <avr_ioport.h>
#include <avr_timer.h>

#include "harness.h"
#include "rig_map.h"

#define PWM_PERIOD_CYCLES 16384  // Timer2 at F_CPU/64, 256 counts
#define HEATER_EMA_S 0.008

static struct harness *g_h;

static struct {
    avr_timer_t *t2;
    avr_io_write_t write;    // simavr's own OCR2A handler
    void *param;
    uint8_t pending;
} g_ocr;
static struct {
    int running;             // the PWM drives the gate (or the pin is forced high)
    uint64_t period_start;   // the running period's BOTTOM
    uint64_t pulse_end;      // when its pulse ends (== period_start: no pulse)
    double ema;              // the plant's view of the duty
    uint64_t on_start;       // the stretch of heating began
    double on_cycles;        // gate-on cycles in the stretch
    uint64_t backdrive_last;
    double backdrive_frac;
} g;

static uint64_t ns_to_cycles(uint64_t ns) { return (ns * 16 + 999) / 1000; }

static int gate_running(const struct harness *h) {
    const uint8_t *d = h->avr->data;
    return (d[REG_TIMSK2] & (1 << TIMSK2_OCIE2A)) || (d[REG_TCCR2A] & (1 << TCCR2A_COM2A1)) ||
           wiring_level(h, RIG_HEATER_PORT, RIG_HEATER_BIT);
}

static avr_cycle_count_t pwm_bottom(struct avr_t *avr, avr_cycle_count_t when, void *param);

// A new PWM period starts: its pulse, and the moving average over the last one.
static void start_period(struct harness *h, uint64_t bottom) {
    const uint8_t *d = h->avr->data;
    const uint64_t period = g_ocr.t2 && g_ocr.t2->tov_cycles > 1 ? g_ocr.t2->tov_cycles : PWM_PERIOD_CYCLES;
    if (g.period_start && bottom > g.period_start) {
        const double last = (double)(g.pulse_end - g.period_start) / (double)(bottom - g.period_start);
        g.ema += (last - g.ema) * (1.0 - exp(-(double)(bottom - g.period_start) / (HEATER_EMA_S * HZ_CPU)));
        if (g.running) g.on_cycles += (double)(g.pulse_end - g.period_start);
    }
    g.period_start = bottom;
    uint64_t pulse = 0;
    if (d[REG_TCCR2A] & (1 << TCCR2A_COM2A1))
        pulse = (uint64_t)(d[REG_OCR2A] + 1) * (period / 256);
    else if (wiring_level(h, RIG_HEATER_PORT, RIG_HEATER_BIT))
        pulse = period;
    g.pulse_end = bottom + pulse;
}

// Called on every register change and every slice.
static void heater_update(struct harness *h) {
    const uint64_t now = h->avr->cycle;
    const uint8_t *d = h->avr->data;
    // OC2A disconnected (or the pin forced low) before the compare: the pulse ends now.
    if (g.pulse_end > now && !(d[REG_TCCR2A] & (1 << TCCR2A_COM2A1)) &&
        !wiring_level(h, RIG_HEATER_PORT, RIG_HEATER_BIT))
        g.pulse_end = now > g.period_start ? now : g.period_start;
    const int running = gate_running(h);
    if (running && !g.running) {
        g.running = 1;
        g.on_start = now;
        g.on_cycles = 0;
        if (g.pulse_end > now) g.on_cycles -= (double)(now - g.period_start);  // count from now
        if (!g_ocr.t2 || g_ocr.t2->tov_cycles <= 1) start_period(h, now);
        else avr_cycle_timer_register(h->avr, g_ocr.t2->tov_base + g_ocr.t2->tov_cycles - now, pwm_bottom, h);
    } else if (!running && g.running) {
        g.running = 0;
        start_period(h, now);  // close the last (partial) period
        g.running = 0;
        const double span = (double)(now - g.on_start);
        if (span < PWM_PERIOD_CYCLES) {  // a register sequence passing through "on": not heating
            avr_cycle_timer_cancel(h->avr, pwm_bottom, h);
            return;
        }
        if (h->heater_periods < HEATER_MAX_PERIODS) {
            h->heater_period_start_s[h->heater_periods] = (double)g.on_start / HZ_CPU;
            h->heater_period_end_s[h->heater_periods] = (double)now / HZ_CPU;
            h->heater_period_duty[h->heater_periods] = span > 0 ? g.on_cycles / span : 0;
        }
        h->heater_periods++;
        h->heater_last_off_s = (double)now / HZ_CPU;
        avr_cycle_timer_cancel(h->avr, pwm_bottom, h);
    }
}

static avr_cycle_count_t pwm_bottom(struct avr_t *avr, avr_cycle_count_t when, void *param) {
    struct harness *h = param;
    start_period(h, when);
    if (!g.running) return 0;
    const uint64_t period = g_ocr.t2 && g_ocr.t2->tov_cycles > 1 ? g_ocr.t2->tov_cycles : PWM_PERIOD_CYCLES;
    (void)avr;
    return when + period;
}

double harness_heater_duty(const struct harness *h) {
    heater_update((struct harness *)h);
    return g.ema;
}

// Counted once per episode: entering the state "heater driven and sense current on".
void drive_check_interlock(struct harness *h) {
    heater_update(h);
    const int bad = h->drive.sense_on && g.running;
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

// TIMSK2 has no handler in simavr (the core writes it): a handler must store the value.
static void on_timsk2(struct avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param) {
    avr_core_watch_write(avr, addr, v);
    drive_check_interlock(param);
}

static avr_cycle_count_t apply_ocr2a(struct avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)when;
    (void)param;
    g_ocr.write(avr, REG_OCR2A, g_ocr.pending, g_ocr.param);
    return 0;
}

// OCR2A written: in fast PWM, effective at the next BOTTOM (see the contract).
static void on_ocr2a(struct avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param) {
    const uint8_t wgm = avr->data[REG_TCCR2A] & 3;
    avr_timer_t *t = g_ocr.t2;
    if (wgm == 3 && t && t->tov_cycles > 1) {
        g_ocr.pending = v;
        const uint64_t bottom = t->tov_base + t->tov_cycles;
        const uint64_t delay = bottom > avr->cycle + 1 ? bottom - avr->cycle - 1 : 1;
        avr_cycle_timer_register(avr, delay, apply_ocr2a, param);
        return;
    }
    avr_cycle_timer_cancel(avr, apply_ocr2a, param);
    g_ocr.write(avr, addr, v, g_ocr.param);
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
    // Take OCR2A's writes over from simavr's timer (its handler is called when they apply).
    const avr_io_addr_t ocr = AVR_DATA_TO_IO(REG_OCR2A);
    memset(&g_ocr, 0, sizeof g_ocr);
    g_ocr.write = h->avr->io[ocr].w.c;
    g_ocr.param = h->avr->io[ocr].w.param;
    for (avr_io_t *io = h->avr->io_port; io; io = io->next)
        if (io->kind && !strcmp(io->kind, "timer") && ((avr_timer_t *)io)->name == '2') g_ocr.t2 = (avr_timer_t *)io;
    h->avr->io[ocr].w.c = on_ocr2a;
    h->avr->io[ocr].w.param = h;
    avr_register_io_write(h->avr, REG_TCCR2A, on_heater_reg, h);
    const avr_io_addr_t timsk2 = AVR_DATA_TO_IO(REG_TIMSK2);
    avr_register_io_write(h->avr, REG_TIMSK2, h->avr->io[timsk2].w.c ? on_heater_reg : on_timsk2, h);
    wiring_pull(h, RIG_STEP_PORT, RIG_STEP_BIT, 0);
    wiring_pull(h, RIG_HEATER_PORT, RIG_HEATER_BIT, 0);
    wiring_pull(h, RIG_ISRC_EN_PORT, RIG_ISRC_EN_BIT, 0);
    wiring_pull(h, RIG_EN_PORT, RIG_EN_BIT, enable_pull_up ? 1 : 0);
    h->drive.enabled = !enable_pull_up;
}

// A4988 data sheet: the translator's Home state is the 45-degree point of the
// microstep table, repeated every four full steps (64 microsteps at 1/16 stepping); a
// UVLO restart puts the phase currents there and the rotor follows to the nearest one.
#define MICROSTEPS_PER_CYCLE 64

void drive_brown_out(struct harness *h) {
    struct drive_state *s = &h->drive;
    const int32_t cycle = MICROSTEPS_PER_CYCLE;
    int32_t r = s->steps % cycle;
    if (r < 0) r += cycle;
    const int32_t shift = r < cycle / 2 ? -r : cycle - r;
    s->steps += shift;
    s->steps_home_shift += shift;
}

// The AVR reset: Timer2 and the ports are back at their reset values.
void drive_reset(struct harness *h) {
    avr_cycle_timer_cancel(h->avr, apply_ocr2a, h);
    if (g.running) {  // simavr dropped the period timer: the PWM stopped with the reset
        g.running = 1;
        avr_cycle_timer_register(h->avr, 1, pwm_bottom, h);
    }
    drive_check_interlock(h);
}
