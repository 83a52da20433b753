// Power stages: the A4988 (STEP/DIR//ENABLE), the AD8276 sense-current enable and the
// heater MOSFET gate.
//
// Contract. Counts a step on each STEP rising edge while /ENABLE is low (DIR high =
// +1), and flags what the real driver would not accept: STEP high or low shorter than
// 1 us, DIR changed within 200 ns before or after a rising edge. The heater duty is
// read from Timer2 (OC2A fast PWM, duty (OCR2A + 1) / 256) or the port bit when the
// compare output is disconnected. Driving the heater while the sense current is on is
// an interlock violation (the firmware must never do it).
#include <string.h>

#include <avr_ioport.h>

#include "harness.h"
#include "rig_map.h"

static struct harness *g_h;

static uint64_t ns_to_cycles(uint64_t ns) { return (ns * 16 + 999) / 1000; }

double harness_heater_duty(const struct harness *h) {
    const uint8_t *d = h->avr->data;
    if (d[REG_TCCR2A] & (1 << TCCR2A_COM2A1)) return (d[REG_OCR2A] + 1) / 256.0;
    return (d[REG_PORTB] >> RIG_HEATER_BIT) & 1 ? 1.0 : 0.0;
}

// Counted once per episode: entering the state "heater driven and sense current on".
void drive_check_interlock(struct harness *h) {
    const int bad = h->drive.sense_on && harness_heater_duty(h) > 0;
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
    h->drive.enabled = !(value & 1);  // /ENABLE is active low
}

static void on_sense(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    struct harness *h = param;
    const int on = value & 1;
    if (on && !h->drive.sense_on) h->drive.sense_on_cycle = h->avr->cycle;
    h->drive.sense_on = on;
    drive_check_interlock(h);
}

static void on_heater_reg(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    (void)value;
    drive_check_interlock(param);
}

int harness_motor_moving(const struct harness *h) {
    const struct drive_state *s = &h->drive;
    return s->steps_total && h->avr->cycle - s->last_step_cycle < h->moving_window_cycles;
}

static void watch(struct harness *h, char port, int bit, avr_irq_notify_t fn) {
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_IOPORT_GETIRQ(port), bit), fn, h);
}

void drive_attach(struct harness *h) {
    g_h = h;
    memset(&h->drive, 0, sizeof h->drive);
    h->drive.enabled = 0;
    watch(h, RIG_STEP_PORT, RIG_STEP_BIT, on_step);
    watch(h, RIG_DIR_PORT, RIG_DIR_BIT, on_dir);
    watch(h, RIG_EN_PORT, RIG_EN_BIT, on_enable);
    watch(h, RIG_ISRC_EN_PORT, RIG_ISRC_EN_BIT, on_sense);
    watch(h, RIG_HEATER_PORT, RIG_HEATER_BIT, on_heater_reg);
}
