// The board's wiring outside the AVR: pull resistors and lines other chips drive.
//
// Contract. simavr 1.6 keeps one "external" mask/value per port (a pin set as input
// reads that value) and AVR_IOCTL_IOPORT_SET_EXTERNAL replaces the whole port's at
// once, so every module that drives or pulls a line goes through here. wiring_pull()
// declares a pull resistor or an external driver on a pin and, when the pin is an
// input, raises its IRQ so the PIN register and every watcher see the level at once
// (simavr raises pin IRQs only on DDR/PORT writes). wiring_level() is the level on the
// wire: the AVR's output when the pin is an output, else the external value, else the
// internal pull-up, else what the PIN register last held (a floating line).
// wiring_reapply() re-asserts everything after a reset (avr_reset zeroes PINx).
#include <string.h>

#include <avr_ioport.h>

#include "harness.h"

#define PORTS 12  // 'A'..'L'

static struct {
    struct harness *h;
    uint8_t mask[PORTS], value[PORTS];
} g;

static int index_of(char port) { return port >= 'A' && port < 'A' + PORTS ? port - 'A' : -1; }

static void apply_port(char port) {
    const int i = index_of(port);
    avr_ioport_external_t ext = {.name = (unsigned)port, .mask = g.mask[i], .value = g.value[i]};
    avr_ioctl(g.h->avr, AVR_IOCTL_IOPORT_SET_EXTERNAL(port), &ext);
}

static int port_state(char port, avr_ioport_state_t *st) {
    return avr_ioctl(g.h->avr, AVR_IOCTL_IOPORT_GETSTATE(port), st);
}

static void raise_if_input(char port, int bit) {
    avr_ioport_state_t st;
    if (port_state(port, &st) < 0 || (st.ddr >> bit) & 1) return;
    const int i = index_of(port);
    const int level = (g.value[i] >> bit) & 1;
    avr_irq_t *irq = avr_io_getirq(g.h->avr, AVR_IOCTL_IOPORT_GETIRQ(port), bit);
    // avr_reset() zeroes PINx but the pin's IRQ keeps its last value, and raising an IRQ
    // to the value it holds notifies nobody: the PIN register would keep the 0 (the
    // firmware then read the CS5513's idle-high SDO as "word ready" until the first
    // conversion and clocked words out of nothing). Make the raise a change when it is one.
    if (((st.pin >> bit) & 1) != level) irq->value = !level;
    avr_raise_irq(irq, level);
}

void wiring_attach(struct harness *h) {
    memset(&g, 0, sizeof g);
    g.h = h;
}

void wiring_pull(struct harness *h, char port, int bit, int level) {
    (void)h;
    const int i = index_of(port);
    if (i < 0) return;
    g.mask[i] |= (uint8_t)(1u << bit);
    if (level)
        g.value[i] |= (uint8_t)(1u << bit);
    else
        g.value[i] &= (uint8_t)~(1u << bit);
    apply_port(port);
    raise_if_input(port, bit);
}

void wiring_release(struct harness *h, char port, int bit) {
    (void)h;
    const int i = index_of(port);
    if (i < 0) return;
    g.mask[i] &= (uint8_t)~(1u << bit);
    g.value[i] &= (uint8_t)~(1u << bit);
    apply_port(port);
}

int wiring_level(const struct harness *h, char port, int bit) {
    (void)h;
    avr_ioport_state_t st;
    const int i = index_of(port);
    if (i < 0 || port_state(port, &st) < 0) return 0;
    if ((st.ddr >> bit) & 1) return (st.port >> bit) & 1;
    if ((g.mask[i] >> bit) & 1) return (g.value[i] >> bit) & 1;
    if ((st.port >> bit) & 1) return 1;
    return (st.pin >> bit) & 1;
}

void wiring_reapply(struct harness *h) {
    (void)h;
    for (int i = 0; i < PORTS; ++i) {
        if (!g.mask[i]) continue;
        apply_port((char)('A' + i));
        for (int bit = 0; bit < 8; ++bit)
            if ((g.mask[i] >> bit) & 1) raise_if_input((char)('A' + i), bit);
    }
}
