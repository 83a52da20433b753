// The I2C bus around simavr's TWI: real byte timing, injected faults, bus recovery.
//
// Contract. simavr 1.6 sets TWINT one microsecond per "TWI cycle" after each TWCR
// write (9 us a byte: 2.5x faster than 400 kHz). After every TWCR write (this module's
// write hook runs after the TWI's own) the pending state timer is re-armed from the bit
// time the registers give, t_bit = 16 + 2 TWBR 4^TWPS CPU cycles (ATmega2560 data sheet
// 24.5.2): a START takes one bit time, an address or data byte with its ACK nine, a STOP
// holds TWSTO set for one bit time (simavr clears it at once). Injected faults, each
// for a window of device time (--twi-fault):
//   nack:T0:T1          the ADS1115 does not acknowledge its address;
//   stretch:T0:T1:US    every byte takes US microseconds longer (clock stretching);
//   stuck:T0[:CLOCKS]   from T0 a slave holds SDA low: no TWI operation completes (TWINT
//                       never rises) until the master, with the TWI off, clocks SCL by
//                       hand CLOCKS times (default 9; the slave then lets SDA go);
//   nackcfg:N           the ADS1115 does not acknowledge the first byte written to its
//                       config register, the first N times (wherever they fall in time:
//                       the switch into continuous mode, its retries).
// SDA and SCL have the board's pull-ups (wiring.c). Counted in the summary: bytes,
// START/STOP, NACKs injected, stretched bytes, stuck events, manual SCL clocks, releases.
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <avr_ioport.h>
#include <avr_twi.h>
#include <sim_cycle_timers.h>

#include "harness.h"
#include "rig_map.h"

#define MAX_FAULTS 8

enum fault_kind { FAULT_NACK, FAULT_STRETCH, FAULT_STUCK, FAULT_NACK_CONFIG };

// Parsed from the command line before the harness exists (twi_bus_add_fault).
static struct {
    int kind;
    double t0, t1, arg;
    int fired;
} g_faults[MAX_FAULTS];
static int g_n_faults;

static struct {
    struct harness *h;
    avr_twi_t *twi;
    int stuck;             // SDA held low now
    int clocks_to_release; // manual SCL rising edges still needed
    int scl_level;
    int stop_pending;
} g;

static uint64_t bit_cycles(void) {
    const uint8_t *d = g.h->avr->data;
    const unsigned twps = d[REG_TWSR] & 3;
    return 16u + 2u * d[REG_TWBR] * (1u << (2 * twps));
}

uint64_t twi_bus_byte_cycles(void) { return 9 * bit_cycles(); }

static int window(int kind, double *arg) {
    const double t = harness_time_s(g.h);
    for (int i = 0; i < g_n_faults; ++i) {
        if (g_faults[i].kind == kind && t >= g_faults[i].t0 && t < g_faults[i].t1) {
            if (arg) *arg = g_faults[i].arg;
            return 1;
        }
    }
    return 0;
}

int twi_bus_nack_config(void) {
    for (int i = 0; i < g_n_faults; ++i) {
        if (g_faults[i].kind == FAULT_NACK_CONFIG && g_faults[i].arg >= 1) {
            g_faults[i].arg -= 1;
            g.h->twi_naks_injected++;
            return 1;
        }
    }
    return 0;
}

int twi_bus_nack_now(void) {
    if (!window(FAULT_NACK, NULL)) return 0;
    g.h->twi_naks_injected++;
    return 1;
}

static void set_stuck(int stuck) {
    g.stuck = stuck;
    wiring_pull(g.h, RIG_SDA_PORT, RIG_SDA_BIT, stuck ? 0 : 1);
}

static void check_stuck_start(void) {
    if (g.stuck) return;
    const double t = harness_time_s(g.h);
    for (int i = 0; i < g_n_faults; ++i) {
        if (g_faults[i].kind == FAULT_STUCK && !g_faults[i].fired && t >= g_faults[i].t0) {
            g_faults[i].fired = 1;
            g.clocks_to_release = g_faults[i].arg > 0 ? (int)g_faults[i].arg : 9;
            g.h->twi_stuck_events++;
            set_stuck(1);
        }
    }
}

// The TWI's own pending state timer (the one that sets TWINT), found by its parameter.
static avr_cycle_timer_slot_p twi_timer(void) {
    for (avr_cycle_timer_slot_p t = g.h->avr->cycle_timers.timer; t; t = t->next)
        if (t->param == g.twi) return t;
    return NULL;
}

static avr_cycle_count_t stop_done(struct avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)when;
    (void)param;
    avr->data[REG_TWCR] &= (uint8_t)~(1u << TWCR_TWSTO);
    g.stop_pending = 0;
    return 0;
}

static void on_twcr_write(struct avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param) {
    (void)addr;
    (void)param;
    if (!(v & (1u << TWCR_TWEN))) return;
    check_stuck_start();
    avr_cycle_timer_slot_p t = twi_timer();
    if (v & (1u << TWCR_TWSTO)) {  // simavr ends the STOP at once; the bus takes a bit time
        g.h->twi_stops++;
        avr->data[REG_TWCR] |= (uint8_t)(1u << TWCR_TWSTO);
        g.stop_pending = 1;
        avr_cycle_timer_register(avr, bit_cycles(), stop_done, NULL);
    }
    if (!t) return;
    avr_cycle_timer_t fn = t->timer;
    if (g.stuck) {  // SDA held low: the operation never completes
        avr_cycle_timer_cancel(avr, fn, g.twi);
        return;
    }
    uint64_t delay;
    if (v & (1u << TWCR_TWSTA)) {
        g.h->twi_starts++;
        delay = bit_cycles();
    } else {
        g.h->twi_bytes++;
        delay = 9 * bit_cycles();
        double us = 0;
        if (window(FAULT_STRETCH, &us)) {
            delay += (uint64_t)(us * HZ_CPU / 1e6);
            g.h->twi_stretched_bytes++;
        }
    }
    avr_cycle_timer_register(avr, delay, fn, g.twi);
}

static void on_scl(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    (void)param;
    const int level = value & 1;
    if (level == g.scl_level) return;
    g.scl_level = level;
    const int twen = (g.h->avr->data[REG_TWCR] >> TWCR_TWEN) & 1;
    if (!level || twen) return;
    g.h->twi_manual_clocks++;  // a rising SCL edge made by hand (bus recovery)
    if (g.stuck && --g.clocks_to_release <= 0) {
        set_stuck(0);  // the slave finished its byte and let SDA go
        g.h->twi_releases++;
    }
}

int twi_bus_add_fault(const char *spec, char *err, size_t errlen) {
    if (g_n_faults >= MAX_FAULTS) {
        snprintf(err, errlen, "at most %d --twi-fault options", MAX_FAULTS);
        return -1;
    }
    char kind[16] = {0};
    double a = -1, b = -1, c = 0;
    const int n = sscanf(spec, "%15[a-z]:%lf:%lf:%lf", kind, &a, &b, &c);
    int k;
    if (!strcmp(kind, "nack") && n == 3) k = FAULT_NACK;
    else if (!strcmp(kind, "stretch") && n == 4) k = FAULT_STRETCH;
    else if (!strcmp(kind, "stuck") && n >= 2) k = FAULT_STUCK;
    else if (!strcmp(kind, "nackcfg") && n == 2 && a >= 1) {
        g_faults[g_n_faults].kind = FAULT_NACK_CONFIG;
        g_faults[g_n_faults].arg = a;
        g_n_faults++;
        return 0;
    } else {
        snprintf(err, errlen, "--twi-fault %s: expected nack:T0:T1, stretch:T0:T1:US, stuck:T0[:CLOCKS] or nackcfg:N",
                 spec);
        return -1;
    }
    if (a < 0 || (k != FAULT_STUCK && b < a)) {
        snprintf(err, errlen, "--twi-fault %s: times must be >= 0 and in order", spec);
        return -1;
    }
    g_faults[g_n_faults].kind = k;
    g_faults[g_n_faults].t0 = a;
    g_faults[g_n_faults].t1 = k == FAULT_STUCK ? 1e300 : b;
    g_faults[g_n_faults].arg = k == FAULT_STRETCH ? c : (n >= 3 ? b : 9);
    g_n_faults++;
    return 0;
}

void twi_bus_attach(struct harness *h) {
    memset(&g, 0, sizeof g);
    g.h = h;
    for (avr_io_t *io = h->avr->io_port; io; io = io->next)
        if (io->kind && strcmp(io->kind, "twi") == 0) g.twi = (avr_twi_t *)io;
    g.scl_level = 1;
    wiring_pull(h, RIG_SCL_PORT, RIG_SCL_BIT, 1);  // the board's pull-ups
    wiring_pull(h, RIG_SDA_PORT, RIG_SDA_BIT, 1);
    avr_register_io_write(h->avr, REG_TWCR, on_twcr_write, NULL);
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_IOPORT_GETIRQ(RIG_SCL_PORT), RIG_SCL_BIT), on_scl, NULL);
}

void twi_bus_reset(struct harness *h) {
    (void)h;
    g.stop_pending = 0;
    g.scl_level = wiring_level(g.h, RIG_SCL_PORT, RIG_SCL_BIT);
}
