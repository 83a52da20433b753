// Worst-case interrupt service durations, measured in the emulated CPU.
//
// Contract. For every registered vector, the cycles from the moment simavr vectors to
// the ISR until its RETI (the 4-5 cycle hardware entry is not included); a nested
// interrupt's time counts in the outer one. Reported per vector that ran.
#include <string.h>

#include <sim_interrupts.h>

#include "harness.h"

static struct harness *g_h;

static void on_running(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    const int v = (int)(intptr_t)param;
    struct harness *h = g_h;
    if (value) {
        h->isr_active[v] = 1;
        h->isr_entered[v] = h->avr->cycle;
    } else if (h->isr_active[v]) {
        h->isr_active[v] = 0;
        const uint64_t d = h->avr->cycle - h->isr_entered[v];
        if (d > h->isr_max_cycles[v]) h->isr_max_cycles[v] = d;
        h->isr_count[v]++;
    }
}

void isr_timing_attach(struct harness *h) {
    g_h = h;
    avr_int_table_p t = &h->avr->interrupts;
    for (int i = 0; i < t->vector_count; ++i) {
        avr_int_vector_t *vec = t->vector[i];
        if (!vec || vec->vector >= 64) continue;
        avr_irq_register_notify(vec->irq + AVR_INT_IRQ_RUNNING, on_running, (void *)(intptr_t)vec->vector);
    }
}
