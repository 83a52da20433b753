// ADS1115 position ADC as an I2C slave on simavr's TWI, plus the TWI quirks of simavr 1.6.
//
// Contract. Answers at its 7-bit address with the ADS1115 register model (data sheet
// SBAS444, section 9.5): a write sets the pointer (0 conversion, 1 config, 2/3
// thresholds) and, with two more bytes, the register; a read returns the pointed
// register MSB first. Writing config with OS = 1 starts a single-shot conversion: OS
// reads 0 for 1/DR s, then the conversion register holds the plant's counts for the
// position sensor at that instant. Conversion starts are timed for the sample-period
// jitter figure.
//
// simavr 1.6 quirks handled here (both counted in the summary):
//  - TWINT is registered "sticky" on the ATmega2560, so a polled master finds it set
//    at once and reads a stale TWSR: twi_quirks_apply() clears raise_sticky.
//  - After SLA+W the model reports 0x28 (data ACK) instead of 0x18 (SLA+W ACK), and
//    0x30 instead of 0x20 for a NACK: the status IRQ hook rewrites TWSR for the one
//    status that follows an address byte.
#include <string.h>

#include <avr_twi.h>

#include "harness.h"
#include "plant_link.h"
#include "rig_map.h"

static struct {
    struct harness *h;
    avr_irq_t *twi_in;
    uint8_t address7;
    int selected;          // addressed in the current transaction
    int write_index;       // bytes received since the address
    uint8_t pointer;
    uint16_t regs[4];      // conversion, config, lo_thresh, hi_thresh
    int converting;
    int expect_address_status;
} g;

static const uint16_t SPS[8] = {8, 16, 32, 64, 128, 250, 475, 860};

static avr_cycle_count_t conversion_done(struct avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)avr;
    (void)param;
    struct harness *h = g.h;
    int32_t counts = 0;
    uint8_t flags = 0;
    h->plant_queries++;
    if (plant_query(h->plant, 'L', harness_time_s(h), h->drive.steps, harness_motor_moving(h),
                    harness_heater_duty(h), &counts, &flags) < 0) {
        strcpy(h->error, "plant connection lost during an ADS1115 conversion");
        avr->state = cpu_Done;
        return 0;
    }
    if (counts > 32767) counts = 32767;
    if (counts < -32768) counts = -32768;
    g.regs[0] = (uint16_t)(int16_t)counts;
    g.regs[1] |= 0x8000;  // OS = 1: idle
    g.converting = 0;
    h->ads_conversions++;
    (void)when;
    return 0;
}

static void start_conversion(void) {
    struct harness *h = g.h;
    const uint64_t now = h->avr->cycle;
    if (h->ads_last_start) {
        const double dt = (double)(now - h->ads_last_start);
        if (!h->ads_intervals || dt < h->ads_interval_min) h->ads_interval_min = dt;
        if (dt > h->ads_interval_max) h->ads_interval_max = dt;
        h->ads_interval_sum += dt;
        h->ads_interval_sq_sum += dt * dt;
        h->ads_intervals++;
    }
    h->ads_last_start = now;
    const uint16_t sps = SPS[(g.regs[1] >> 5) & 7];
    g.regs[1] &= 0x7FFF;  // OS reads 0 while converting
    g.converting = 1;
    avr_cycle_timer_cancel(h->avr, conversion_done, NULL);
    avr_cycle_timer_register(h->avr, (avr_cycle_count_t)(HZ_CPU / sps), conversion_done, NULL);
}

static void reply(uint8_t msg, uint8_t addr, uint8_t data) {
    avr_raise_irq(g.twi_in, avr_twi_irq_msg(msg, addr, data));
}

static void on_twi(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    (void)param;
    avr_twi_msg_irq_t m;
    m.u.v = value;
    const uint8_t msg = m.u.twi.msg, addr = m.u.twi.addr, data = m.u.twi.data;
    if (msg & TWI_COND_STOP) {
        g.selected = 0;
    }
    if (msg & TWI_COND_START) {
        g.selected = (addr >> 1) == g.address7;
        g.write_index = 0;
        g.expect_address_status = 1;
        g.h->twi_transactions++;
        if (g.selected)
            reply(TWI_COND_ACK, addr, 1);
        else
            g.h->twi_naks++;
    }
    if (!g.selected) return;
    if (msg & TWI_COND_WRITE) {
        reply(TWI_COND_ACK, addr, 1);
        if (g.write_index == 0) {
            g.pointer = data & 3;
        } else if (g.write_index == 1) {
            g.regs[g.pointer] = (uint16_t)((g.regs[g.pointer] & 0x00FF) | data << 8);
        } else if (g.write_index == 2) {
            g.regs[g.pointer] = (uint16_t)((g.regs[g.pointer] & 0xFF00) | data);
            if (g.pointer == 1) {
                const int os = g.regs[1] & 0x8000;
                const int single = g.regs[1] & 0x0100;
                if (os && single && !g.converting) start_conversion();
                else if (g.converting) g.regs[1] &= 0x7FFF;
            }
        }
        g.write_index++;
    }
    if (msg & TWI_COND_READ) {
        // The master asks for the next byte: MSB first, then LSB, then repeat.
        const uint16_t v = g.regs[g.pointer];
        const uint8_t byte = (g.write_index & 1) ? (uint8_t)v : (uint8_t)(v >> 8);
        g.write_index++;
        reply(TWI_COND_READ, addr, byte);
    }
}

static void on_twi_status(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    (void)param;
    if (!g.expect_address_status) return;
    g.expect_address_status = 0;
    uint8_t *twsr = &g.h->avr->data[REG_TWSR];
    if (value == 0x28 || value == 0x30) {
        *twsr = (uint8_t)((*twsr & 0x07) | (value == 0x28 ? 0x18 : 0x20));
        g.h->twi_status_fixes++;
    }
}

void twi_quirks_apply(struct harness *h) {
    for (avr_io_t *io = h->avr->io_port; io; io = io->next) {
        if (io->kind && strcmp(io->kind, "twi") == 0) {
            avr_twi_t *twi = (avr_twi_t *)io;
            twi->twi.raise_sticky = 0;
        }
    }
}

void ads1115_attach(struct harness *h, uint8_t address7) {
    memset(&g, 0, sizeof g);
    g.h = h;
    g.address7 = address7;
    g.regs[1] = 0x8583;  // power-on default config
    g.regs[2] = 0x8000;
    g.regs[3] = 0x7FFF;
    g.twi_in = avr_io_getirq(h->avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_INPUT);
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_OUTPUT), on_twi, NULL);
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_STATUS), on_twi_status, NULL);
    twi_quirks_apply(h);
}
