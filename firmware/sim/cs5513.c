// CS5513 resistance ADC on its 3-wire port (/CS, SCLK, SDO), fed by the plant.
//
// Contract, from the data sheet (DS337, CS5510/11/12/13) and not from the firmware's
// driver:
//  - Conversions: with /CS low the converter runs continuously at CLK/612 (the CS5513's
//    on-chip oscillator runs 32..96 kHz: 53..159 words/s; --cs5513-conversion-us sets
//    the period, 19125 us at the slowest). /CS high puts it to sleep.
//  - Filter: a modified sinc^4, four conversion periods long; "after initial power up,
//    or after returning from sleep mode, the filter requires four conversion cycles"
//    to settle. Modelled as the cubic B-spline the four cascaded averages make, sampled
//    at the four conversion instants it spans: weights 1/48, 23/48, 23/48, 1/48 (oldest
//    first); the input is the plant's resistance reading while the 50 mA sense current
//    is on, 0 while it is off or before the wake (the filter starts empty).
//  - Output word (Table 1, CS5512/13: flags + 20 bits), MSB first: D23 = 0, D22 = OF
//    (overrange: input beyond full scale; the code saturates), D21 = OD (oscillation
//    detect: the modulator went unstable on an input far beyond full scale, here twice
//    it; "cleared four output words after the modulator becomes stable again"), D20 = 0,
//    D19..D0 two's complement.
//  - Serial port: a finished conversion pulls SDO low (D23 = 0 doubles as "data
//    ready"); each SCLK falling edge shifts the next bit out; after 24 bits SDO returns
//    high. SCLK must stay high and low at least 250 ns (the family's serial timing,
//    t1/t2): shorter pulses are counted as violations. A new word replaces an unread one,
//    but not one being clocked out: the output register holds until the read completes
//    and that conversion's word is lost. Clocking with nothing ready is a partial read.
//  - SDO is high impedance with /CS high (the firmware's pull-up then reads 1), driven
//    high from the wake until a word is ready (without that a floating SDO read 0 in
//    simavr, the firmware clocked "words" out of nothing, and a conversion finishing
//    mid-clocking left a read half done that blocked every later word); /CS has
//    a pull-up on the board, so the part sleeps while the AVR resets.
#include <string.h>

#include <avr_ioport.h>

#include "harness.h"
#include "plant_link.h"
#include "rig_map.h"

static struct {
    struct harness *h;
    uint64_t conversion_cycles;
    int cs_low, sclk;
    int32_t history[4];
    int filled;
    uint32_t word;
    int ready;             // a word waits to be clocked out
    int bit;               // next bit index to present (0 = bit 23)
    int reading;
    int od_words;          // words still flagged OD after the modulator recovered
    uint64_t sclk_edge;    // cycle of the last SCLK edge
} g;

// SDO is driven by the converter: declared as an external drive (wiring.c), because
// simavr 1.6 otherwise lets the AVR's internal pull-up (PORTC2 = 1) overwrite the pin
// on every PORTC write (the /CS and SCLK writes), and the firmware would read 1s only.
static void drive_sdo(int level) { wiring_pull(g.h, RIG_RES_SDO_PORT, RIG_RES_SDO_BIT, level); }

static avr_cycle_count_t conversion(struct avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)param;
    struct harness *h = g.h;
    if (!g.cs_low) return 0;
    int32_t counts = 0;
    uint8_t flags = 0;
    if (h->drive.sense_on) {
        h->plant_queries++;
        if (plant_query(h->plant, 'R', harness_time_s(h), h->drive.steps, harness_motor_moving(h),
                        harness_heater_duty(h), &counts, &flags) < 0) {
            strcpy(h->error, "plant connection lost during a CS5513 conversion");
            avr->state = cpu_Done;
            return 0;
        }
    }
    memmove(g.history, g.history + 1, 3 * sizeof g.history[0]);
    g.history[3] = counts;
    if (g.filled < 4) g.filled++;
    static const int W[4] = {1, 23, 23, 1};  // sinc^4 as a cubic B-spline, /48
    int64_t sum = 0;
    for (int i = 0; i < 4; ++i) sum += (int64_t)W[i] * g.history[i];
    int64_t value = sum >= 0 ? (sum + 24) / 48 : -((-sum + 24) / 48);
    uint32_t word = 0;
    const int far = counts > 2 * 0x7FFFF || counts < -2 * 0x80000;
    if (far) g.od_words = 4;  // the modulator is unstable; OD stays for four words after
    if (g.od_words > 0) {
        word |= 1UL << 21;
        if (!far) g.od_words--;
        h->cs_od_words++;
    }
    if (value > 0x7FFFF || (flags & 1)) {
        value = value > 0 ? 0x7FFFF : -0x80000;
        word |= 1UL << 22;
    } else if (value < -0x80000) {
        value = -0x80000;
        word |= 1UL << 22;
    }
    word |= (uint32_t)value & 0xFFFFFUL;
    if (g.reading) return when + g.conversion_cycles;  // output register busy
    g.word = word;
    g.ready = 1;
    g.bit = 0;
    g.reading = 0;
    h->cs_conversions++;
    drive_sdo(0);  // bit 23 = 0 doubles as "data ready"
    return when + g.conversion_cycles;
}

static void on_cs(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    (void)param;
    const int low = !(value & 1);
    if (low == g.cs_low) return;
    g.cs_low = low;
    avr_cycle_timer_cancel(g.h->avr, conversion, NULL);
    if (low) {  // wake: the filter starts empty; SDO drives high until the first word is ready
        memset(g.history, 0, sizeof g.history);
        g.filled = 0;
        g.ready = 0;
        g.reading = 0;
        drive_sdo(1);
        avr_cycle_timer_register(g.h->avr, g.conversion_cycles, conversion, NULL);
    } else {
        g.ready = 0;
        drive_sdo(1);
    }
}

static void on_sclk(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    (void)param;
    const int level = value & 1;
    if (level == g.sclk) return;
    g.sclk = level;
    const uint64_t now = g.h->avr->cycle;
    if (g.cs_low && g.sclk_edge && now - g.sclk_edge < CS5513_MIN_SCLK_CYCLES) g.h->cs_sclk_violations++;
    g.sclk_edge = now;
    if (!g.cs_low) return;
    if (level) {
        if (!g.ready) g.h->cs_partial_reads++;
        else g.reading = 1;
        return;
    }
    if (!g.ready) return;
    g.bit++;
    if (g.bit >= 24) {
        g.ready = 0;
        g.reading = 0;
        g.h->cs_words_read++;
        drive_sdo(1);
    } else {
        drive_sdo((g.word >> (23 - g.bit)) & 1);
    }
}

void cs5513_attach(struct harness *h, double conversion_us) {
    memset(&g, 0, sizeof g);
    g.h = h;
    g.conversion_cycles = (uint64_t)(conversion_us * HZ_CPU / 1e6);
    g.sclk = 0;
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_IOPORT_GETIRQ(RIG_RES_CS_PORT), RIG_RES_CS_BIT),
                            on_cs, NULL);
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_IOPORT_GETIRQ(RIG_RES_SCLK_PORT), RIG_RES_SCLK_BIT),
                            on_sclk, NULL);
    g.cs_low = 0;
    wiring_pull(h, RIG_RES_CS_PORT, RIG_RES_CS_BIT, 1);  // /CS pull-up: asleep while the AVR resets
    drive_sdo(1);
}

// The AVR reset; the converter did not. /CS floats high (its pull-up): asleep.
void cs5513_reset(struct harness *h) {
    (void)h;
    g.reading = 0;
    if (g.cs_low) avr_cycle_timer_register(g.h->avr, g.conversion_cycles, conversion, NULL);
}
