// ADS1115 position ADC as an I2C slave on simavr's TWI, with its register map.
//
// Contract (data sheet SBAS444, section 9.6). Four registers behind the pointer
// register (a write's first byte, 2 LSBs; a read returns the pointed register MSB
// first): conversion, config, Lo_thresh, Hi_thresh. Config fields, all honoured:
//   OS (15)      write 1 in power-down (single-shot) mode: start one conversion; read:
//                0 while converting, 1 when idle (always 0 in continuous mode);
//   MUX (14:12)  000 AIN0-AIN1, 001 AIN0-AIN3, 010 AIN1-AIN3, 011 AIN2-AIN3,
//                100..111 AINx-GND; AIN0 carries the position sensor (the plant's
//                voltage), AIN1..3 are grounded;
//   PGA (11:9)   full scale +-6.144, 4.096, 2.048, 1.024, 0.512, 0.256 V (101..111);
//                the code is V / (FS / 32768) rounded, clamped to -32768..32767;
//   MODE (8)     1 single-shot, 0 continuous (a conversion every 1/DR);
//   DR (7:5)     8..860 samples/s: a conversion lasts 1/DR, times (1 + --ads-rate-error)
//                for the part's oscillator (+-10 % in the data sheet);
//   COMP_MODE/POL/LAT/QUE (4:0): the comparator (traditional or window, latching or
//                not, asserting after 1, 2 or 4 conversions beyond the thresholds, 11 =
//                off); its assertions are counted.
// ALERT/RDY (open drain, the board's pull-up, wired to PE4 = INT4): with Hi_thresh's MSB
// 1, Lo_thresh's MSB 0 and COMP_QUE not 11 it is the conversion-ready pin (9.3.8): in
// continuous mode it pulses low for ~8 us at the end of every conversion (COMP_POL = 1:
// a high pulse). The comparator is then off. Pulses are counted (ads.rdy_pulses).
// --rdy-cut T0[:T1] cuts the ALERT/RDY wire between T0 and T1 s of device time (T1
// omitted: for good, an unwired D2): the chip converts on, no pulse reaches the AVR
// (counted: ads.rdy_pulses_cut).
// A conversion starts when the config write's last byte has been shifted in (nine bit
// times after the byte's TWCR write, twi_bus.c); in continuous mode each next one starts
// as the one before ends (its ALERT/RDY edge). Every start is the sampler's real timing
// (jitter figure; --trace writes each as `ads_start <us> <steps>`: the firmware's clock
// and the A4988's step count then). The plant's position reading is requested at
// the end of the conversion. Faults injected on the bus (NACK, stretching, a stuck SDA)
// come from twi_bus.c.
//
// simavr 1.6 quirks handled here (both counted in the summary):
//  - TWINT is registered "sticky" on the ATmega2560, so a polled master finds it set
//    at once and reads a stale TWSR: twi_quirks_apply() clears raise_sticky.
//  - After SLA+W the model reports 0x28 (data ACK) instead of 0x18 (SLA+W ACK), and
//    0x30 instead of 0x20 for a NACK: the status IRQ hook rewrites TWSR for the one
//    status that follows an address byte.
#include <math.h>
#include <string.h>

#include <avr_twi.h>

#include "harness.h"
#include "plant_link.h"
#include "rig_map.h"

// The plant's position reading is in counts at the bench's calibration, which assumes
// PGA +-6.144 V (187.5 uV per count): that is the voltage on AIN0.
#define PLANT_VOLTS_PER_COUNT 187.5e-6

static struct {
    struct harness *h;
    avr_irq_t *twi_in;
    uint8_t address7;
    int selected;          // addressed in the current transaction
    int write_index;       // bytes received since the address
    uint8_t pointer;
    uint16_t regs[4];      // conversion, config, lo_thresh, hi_thresh
    int converting;
    int continuous;
    int expect_address_status;
    int comp_count;        // consecutive conversions beyond the threshold
    int alert;             // ALERT/RDY asserted (latched or not)
    double rate_error;
    FILE *trace;
    uint64_t done_cycle;   // when the latest conversion finished
    int unread;            // the latest conversion has not been read yet
} g;

#define MAX_RDY_CUTS 4
static double g_cut_t0[MAX_RDY_CUTS], g_cut_t1[MAX_RDY_CUTS];
static int g_n_cuts;

int ads1115_add_rdy_cut(const char *spec) {
    double a = -1, b = 1e300;
    const int n = sscanf(spec, "%lf:%lf", &a, &b);
    if (g_n_cuts >= MAX_RDY_CUTS || n < 1 || a < 0 || b < a) return -1;
    g_cut_t0[g_n_cuts] = a;
    g_cut_t1[g_n_cuts] = b;
    g_n_cuts++;
    return 0;
}

static int rdy_cut_now(void) {
    const double t = harness_time_s(g.h);
    for (int i = 0; i < g_n_cuts; ++i)
        if (t >= g_cut_t0[i] && t < g_cut_t1[i]) return 1;
    return 0;
}

static const uint16_t SPS[8] = {8, 16, 32, 64, 128, 250, 475, 860};
static const double FS_V[8] = {6.144, 4.096, 2.048, 1.024, 0.512, 0.256, 0.256, 0.256};

static uint64_t conversion_cycles(void) {
    const uint16_t sps = SPS[(g.regs[1] >> 5) & 7];
    return (uint64_t)(HZ_CPU / sps * (1.0 + g.rate_error));
}

static double input_volts(double ain0) {
    switch ((g.regs[1] >> 12) & 7) {
        case 0: return ain0;   // AIN0 - AIN1
        case 1: return ain0;   // AIN0 - AIN3
        case 4: return ain0;   // AIN0 - GND
        default: return 0.0;   // the grounded inputs
    }
}

static void comparator(int16_t code) {
    const uint16_t c = g.regs[1];
    const unsigned que = c & 3;
    if (que == 3) {  // disabled: ALERT/RDY high impedance
        g.alert = 0;
        g.comp_count = 0;
        return;
    }
    const int window_mode = (c >> 4) & 1, latching = (c >> 2) & 1;
    const int16_t lo = (int16_t)g.regs[2], hi = (int16_t)g.regs[3];
    const int beyond = window_mode ? (code > hi || code < lo) : code > hi;
    g.comp_count = beyond ? g.comp_count + 1 : 0;
    const int needed = que == 0 ? 1 : que == 1 ? 2 : 4;
    if (g.comp_count >= needed && !g.alert) {
        g.alert = 1;
        g.h->ads_alerts++;
    } else if (!latching && !window_mode && code < lo) {
        g.alert = 0;  // traditional, non-latching: de-asserts below Lo_thresh
    } else if (!latching && window_mode && !beyond) {
        g.alert = 0;
    }
}

static int rdy_mode(void) {
    return (g.regs[3] & 0x8000) && !(g.regs[2] & 0x8000) && (g.regs[1] & 3) != 3;
}

static int rdy_idle_level(void) { return ((g.regs[1] >> 3) & 1) ? 0 : 1; }  // COMP_POL

static avr_cycle_count_t rdy_release(struct avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)avr;
    (void)when;
    (void)param;
    wiring_pull(g.h, RIG_ADS_RDY_PORT, RIG_ADS_RDY_BIT, rdy_idle_level());
    return 0;
}

static void note_start(uint64_t start);

static avr_cycle_count_t conversion_done(struct avr_t *avr, avr_cycle_count_t when, void *param) {
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
    const double fs = FS_V[(g.regs[1] >> 9) & 7];
    double code = round(input_volts(counts * PLANT_VOLTS_PER_COUNT) / (fs / 32768.0));
    if (code > 32767) code = 32767;
    if (code < -32768) code = -32768;
    g.regs[0] = (uint16_t)(int16_t)code;
    h->ads_conversions++;
    if (g.continuous && g.unread && rdy_mode()) {  // the one before was never read: a lost sample
        h->ads_unread++;
        if (g.trace) fprintf(g.trace, "ads_unread %.3f pc 0x%05x\n", harness_app_us(h, avr->cycle), avr->pc);
    }
    g.unread = 1;
    g.done_cycle = avr->cycle;
    if (rdy_mode()) {
        if (g.continuous && rdy_cut_now()) {
            h->ads_rdy_pulses_cut++;
        } else if (g.continuous) {
            wiring_pull(h, RIG_ADS_RDY_PORT, RIG_ADS_RDY_BIT, !rdy_idle_level());
            avr_cycle_timer_register(avr, ADS1115_RDY_PULSE_CYCLES, rdy_release, NULL);
            h->ads_rdy_pulses++;
        }
    } else {
        comparator((int16_t)code);
    }
    if (g.continuous) {
        note_start(when);  // the next conversion starts as this one ends
        return when + conversion_cycles();
    }
    g.regs[1] |= 0x8000;  // OS = 1: idle
    g.converting = 0;
    return 0;
}

static void note_start(uint64_t start) {
    struct harness *h = g.h;
    if (h->ads_last_start) {
        const double dt = (double)(start - h->ads_last_start);
        if (!h->ads_intervals || dt < h->ads_interval_min) h->ads_interval_min = dt;
        if (dt > h->ads_interval_max) h->ads_interval_max = dt;
        h->ads_interval_sum += dt;
        h->ads_interval_sq_sum += dt * dt;
        h->ads_intervals++;
    }
    h->ads_last_start = start;
    if (g.trace) fprintf(g.trace, "ads_start %.3f %d\n", harness_app_us(h, start), (int)h->drive.steps);
}

// The config register was written (its LSB just arrived).
static void config_written(void) {
    struct harness *h = g.h;
    const uint16_t c = g.regs[1];
    const uint64_t start = h->avr->cycle + twi_bus_byte_cycles();  // after the byte is shifted in
    avr_cycle_timer_cancel(h->avr, conversion_done, NULL);
    if (!(c & 0x0100)) {  // continuous mode
        g.continuous = 1;
        g.converting = 1;
        g.regs[1] &= 0x7FFF;
        note_start(start);
        avr_cycle_timer_register(h->avr, start - h->avr->cycle + conversion_cycles(), conversion_done, NULL);
        return;
    }
    g.continuous = 0;
    if (c & 0x8000) {  // OS = 1 in single-shot mode: one conversion
        g.regs[1] &= 0x7FFF;
        g.converting = 1;
        note_start(start);
        avr_cycle_timer_register(h->avr, start - h->avr->cycle + conversion_cycles(), conversion_done, NULL);
    } else {
        g.converting = 0;
        g.regs[1] |= 0x8000;
    }
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
        g.selected = (addr >> 1) == g.address7 && !twi_bus_nack_now();
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
        if (g.write_index == 1 && g.pointer == 1 && twi_bus_nack_config()) {
            g.selected = 0;  // not acknowledged (nackcfg): the write ends here, nothing applied
            return;
        }
        reply(TWI_COND_ACK, addr, 1);
        if (g.write_index == 0) {
            g.pointer = data & 3;
        } else if (g.pointer == 0) {
            // the conversion register is read-only
        } else if (g.write_index == 1) {
            g.regs[g.pointer] = (uint16_t)((g.regs[g.pointer] & 0x00FF) | data << 8);
        } else if (g.write_index == 2) {
            g.regs[g.pointer] = (uint16_t)((g.regs[g.pointer] & 0xFF00) | data);
            if (g.pointer == 1) config_written();
        }
        g.write_index++;
    }
    if (msg & TWI_COND_READ) {
        // The master asks for the next byte: MSB first, then LSB, then repeat.
        uint16_t v = g.regs[g.pointer];
        if (g.pointer == 0 && !(g.write_index & 1) && g.unread) {  // the MSB of a fresh conversion
            const double us = (double)(g.h->avr->cycle - g.done_cycle) * 1e6 / HZ_CPU;
            if (us > g.h->ads_read_latency_max_us) g.h->ads_read_latency_max_us = us;
            g.unread = 0;
        }
        if (g.pointer == 1) v = (uint16_t)((v & 0x7FFF) | (g.converting || g.continuous ? 0 : 0x8000));
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

void ads1115_attach(struct harness *h, uint8_t address7, double rate_error, FILE *trace) {
    memset(&g, 0, sizeof g);
    g.h = h;
    g.address7 = address7;
    g.rate_error = rate_error;
    g.trace = trace;
    g.regs[1] = 0x8583;  // power-on default config: single-shot, powered down
    g.regs[2] = 0x8000;
    g.regs[3] = 0x7FFF;
    wiring_pull(h, RIG_ADS_RDY_PORT, RIG_ADS_RDY_BIT, 1);  // the board's pull-up
    g.twi_in = avr_io_getirq(h->avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_INPUT);
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_OUTPUT), on_twi, NULL);
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_STATUS), on_twi_status, NULL);
    twi_quirks_apply(h);
}

// The AVR reset (the ADC did not): a conversion under way still finishes.
void ads1115_reset(struct harness *h) {
    g.selected = 0;
    g.expect_address_status = 0;
    if (g.converting || g.continuous)
        avr_cycle_timer_register(h->avr, conversion_cycles(), conversion_done, NULL);
    twi_quirks_apply(h);
}
