// CS5513 resistance ADC on its 3-wire port (/CS, SCLK, SDO), fed by the plant.
//
// Contract (data sheet DS337, as the firmware's drivers/cs5513.h reads it). With /CS
// low the converter runs continuously, one word every `conversion_us`; /CS high puts
// it to sleep and restarts its sinc4 filter. Each word is the mean of the last four
// instantaneous inputs (the filter spans about four conversions), the input being the
// plant's resistance counts while the 50 mA sense current is on and 0 while it is off;
// so words right after the current switches on are wrong, as on the real part. A ready
// word pulls SDO low (its bit 23, always 0); each SCLK falling edge shifts the next bit
// out (bit 22 OF, 21 OD, 20 0, 19..0 two's complement data); after 24 bits SDO returns
// high. A new word replaces an unread one, but not one being clocked out: the output
// register holds until the read completes and that conversion's word is lost (as the
// part's serial port does). Clocking with nothing ready is counted as a partial read.
#include <string.h>

#include <avr_ioport.h>

#include "harness.h"
#include "plant_link.h"
#include "rig_map.h"

static struct {
    struct harness *h;
    avr_irq_t *sdo;
    uint64_t conversion_cycles;
    int cs_low, sclk;
    int32_t history[4];
    int filled;
    uint32_t word;
    int ready;             // a word waits to be clocked out
    int bit;               // next bit index to present (0 = bit 23)
    int reading;
} g;

// SDO is driven by the converter: declared as an external drive, because simavr 1.6
// otherwise lets the AVR's internal pull-up (PORTC2 = 1) overwrite the pin on every
// PORTC write (the /CS and SCLK writes), and the firmware would read 1s only.
static void drive_sdo(int level) {
    avr_ioport_external_t ext = {.name = RIG_RES_SDO_PORT, .mask = 1u << RIG_RES_SDO_BIT,
                                 .value = (unsigned)(level ? 1u : 0u) << RIG_RES_SDO_BIT};
    avr_ioctl(g.h->avr, AVR_IOCTL_IOPORT_SET_EXTERNAL(RIG_RES_SDO_PORT), &ext);
    avr_raise_irq(g.sdo, level ? 1 : 0);
}

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
    int64_t sum = 0;
    for (int i = 0; i < 4; ++i) sum += g.history[i];
    int32_t value = (int32_t)(sum / 4);
    uint32_t word = 0;
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
    if (low) {  // wake: the filter starts empty
        memset(g.history, 0, sizeof g.history);
        g.filled = 0;
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
    g.sdo = avr_io_getirq(h->avr, AVR_IOCTL_IOPORT_GETIRQ(RIG_RES_SDO_PORT), RIG_RES_SDO_BIT);
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_IOPORT_GETIRQ(RIG_RES_CS_PORT), RIG_RES_CS_BIT),
                            on_cs, NULL);
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_IOPORT_GETIRQ(RIG_RES_SCLK_PORT), RIG_RES_SCLK_BIT),
                            on_sclk, NULL);
    drive_sdo(1);
}
