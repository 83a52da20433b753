// See summary.h. Keys carry their units (_s, _us, _cycles, _bytes_per_s).
#include "summary.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static const char *vector_name(int v) {
    switch (v) {
        case 5: return "INT4";
        case 12: return "WDT";
        case 13: return "TIMER2_COMPA";
        case 17: return "TIMER1_COMPA";
        case 25: return "USART0_RX";
        case 26: return "USART0_UDRE";
        case 35: return "TIMER3_OVF";
        case 39: return "TWI";
        default: return NULL;
    }
}

static void json_string(FILE *f, const char *s) {
    fputc('"', f);
    for (; *s; ++s) {
        if (*s == '"' || *s == '\\') fputc('\\', f);
        if ((unsigned char)*s < 0x20) fprintf(f, "\\u%04x", *s);
        else fputc(*s, f);
    }
    fputc('"', f);
}

int summary_write(const struct harness *h, const char *path, const char *elf, const char *reason, int crashed,
                  double wall_s) {
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    const double t = (double)h->avr->cycle / HZ_CPU;
    const struct drive_state *d = &h->drive;
    fprintf(f, "{\n  \"elf\": ");
    json_string(f, elf);
    fprintf(f, ",\n  \"mcu\": \"atmega2560\",\n  \"f_cpu_hz\": %.0f,\n", HZ_CPU);
    fprintf(f, "  \"cycles\": %llu,\n  \"device_time_s\": %.6f,\n  \"wall_time_s\": %.3f,\n",
            (unsigned long long)h->avr->cycle, t, wall_s);
    fprintf(f, "  \"stop_reason\": ");
    json_string(f, reason);
    fprintf(f, ",\n  \"crashed\": %s,\n  \"resets\": %llu,\n  \"app_starts\": %llu,\n  \"pc\": %u,\n",
            crashed ? "true" : "false", (unsigned long long)h->resets, (unsigned long long)h->app_starts,
            (unsigned)h->avr->pc);
    fprintf(f, "  \"reset_log\": [");
    for (int i = 0; i < h->n_reset_log; ++i)
        fprintf(f, "%s{\"t_s\": %.6f, \"cause\": \"%s\"}", i ? ", " : "", h->reset_t_s[i], h->reset_cause[i]);
    fprintf(f, "],\n  \"clock_zero_s\": %.6f,\n", (double)h->t3_zero_cycle / HZ_CPU);
    fprintf(f, "  \"steps\": {\"position\": %ld, \"total\": %llu, \"while_disabled\": %llu,"
               " \"backdriven\": %llu, \"home_shift\": %lld, \"min_high_cycles\": %llu, \"min_low_cycles\": %llu},\n",
            (long)d->steps, (unsigned long long)d->steps_total, (unsigned long long)d->steps_while_disabled,
            (unsigned long long)d->steps_backdriven, (long long)d->steps_home_shift,
            (unsigned long long)d->min_step_high_cycles,
            (unsigned long long)d->min_step_low_cycles);
    fprintf(f, "  \"drive\": {\"enabled\": %s, \"disables\": %llu, \"last_disable_s\": %.6f,"
               " \"sense_on\": %s, \"last_sense_off_s\": %.6f},\n",
            d->enabled ? "true" : "false", (unsigned long long)d->disables, (double)d->last_disable_cycle / HZ_CPU,
            d->sense_on ? "true" : "false", (double)d->last_sense_off_cycle / HZ_CPU);
    fprintf(f, "  \"heater\": {\"last_off_s\": %.6f, \"periods\": [", h->heater_last_off_s);
    const uint64_t np = h->heater_periods < HEATER_MAX_PERIODS ? h->heater_periods : HEATER_MAX_PERIODS;
    for (uint64_t i = 0; i < np; ++i)
        fprintf(f, "%s{\"start_s\": %.6f, \"end_s\": %.6f, \"mean_duty\": %.7f}", i ? ", " : "",
                h->heater_period_start_s[i], h->heater_period_end_s[i], h->heater_period_duty[i]);
    fprintf(f, "]},\n");
    fprintf(f, "  \"violations\": {\"step_pulse_width\": %llu, \"dir_setup\": %llu, \"dir_hold\": %llu,"
               " \"heater_sense_interlock\": %llu, \"uart_rx_overrun\": %llu},\n",
            (unsigned long long)d->pulse_width_violations, (unsigned long long)d->dir_setup_violations,
            (unsigned long long)d->dir_hold_violations, (unsigned long long)d->interlock_violations,
            (unsigned long long)h->uart_rx_overruns);
    const double tx_span_s = (double)(h->uart_tx_last_cycle - h->uart_tx_first_cycle) / HZ_CPU;
    const double burst_s = (double)h->uart_tx_longest_burst_cycles / HZ_CPU;
    const double burst_rate = burst_s > 0 ? (double)(h->uart_tx_longest_burst_bytes - 1) / burst_s : 0.0;
    fprintf(f, "  \"uart\": {\"rx_bytes\": %llu, \"tx_bytes\": %llu, \"tx_span_s\": %.6f,"
               " \"tx_longest_burst_bytes\": %llu, \"tx_burst_bytes_per_s\": %.1f,"
               " \"held_before_rxen\": %llu, \"byte_time_fixes\": %llu},\n",
            (unsigned long long)h->uart_rx_bytes, (unsigned long long)h->uart_tx_bytes, tx_span_s,
            (unsigned long long)h->uart_tx_longest_burst_bytes, burst_rate,
            (unsigned long long)h->uart_rx_held_before_rxen, (unsigned long long)h->uart_cycles_per_byte_fixes);
    fprintf(f, "  \"host\": {\"last_rx_s\": %.6f},\n", (double)uart_bridge_host_rx_cycle() / HZ_CPU);
    fprintf(f, "  \"twi\": {\"transactions\": %llu, \"naks\": %llu, \"status_fixes\": %llu, \"starts\": %llu,"
               " \"stops\": %llu, \"bytes\": %llu, \"naks_injected\": %llu, \"stretched_bytes\": %llu,"
               " \"stuck_events\": %llu, \"manual_scl_clocks\": %llu, \"releases\": %llu},\n",
            (unsigned long long)h->twi_transactions, (unsigned long long)h->twi_naks,
            (unsigned long long)h->twi_status_fixes, (unsigned long long)h->twi_starts,
            (unsigned long long)h->twi_stops, (unsigned long long)h->twi_bytes,
            (unsigned long long)h->twi_naks_injected, (unsigned long long)h->twi_stretched_bytes,
            (unsigned long long)h->twi_stuck_events, (unsigned long long)h->twi_manual_clocks,
            (unsigned long long)h->twi_releases);
    fprintf(f, "  \"adc\": {\"ads1115_conversions\": %llu, \"ads1115_alerts\": %llu, \"ads1115_rdy_pulses\": %llu,"
               " \"ads1115_rdy_pulses_cut\": %llu, \"ads1115_unread\": %llu, \"ads1115_read_latency_max_us\": %.1f,"
               " \"cs5513_conversions\": %llu,"
               " \"cs5513_words_read\": %llu, \"cs5513_partial_reads\": %llu, \"cs5513_od_words\": %llu,"
               " \"cs5513_sclk_violations\": %llu, \"plant_queries\": %llu},\n",
            (unsigned long long)h->ads_conversions, (unsigned long long)h->ads_alerts,
            (unsigned long long)h->ads_rdy_pulses, (unsigned long long)h->ads_rdy_pulses_cut,
            (unsigned long long)h->ads_unread, h->ads_read_latency_max_us,
            (unsigned long long)h->cs_conversions, (unsigned long long)h->cs_words_read,
            (unsigned long long)h->cs_partial_reads, (unsigned long long)h->cs_od_words,
            (unsigned long long)h->cs_sclk_violations, (unsigned long long)h->plant_queries);
    const double n = (double)h->ads_intervals;
    const double mean = n > 0 ? h->ads_interval_sum / n : 0;
    const double var = n > 1 ? (h->ads_interval_sq_sum - n * mean * mean) / (n - 1) : 0;
    const double us = 1e6 / HZ_CPU;
    fprintf(f, "  \"sample_interval\": {\"count\": %llu, \"mean_us\": %.3f, \"std_us\": %.3f,"
               " \"min_us\": %.3f, \"max_us\": %.3f},\n",
            (unsigned long long)h->ads_intervals, mean * us, var > 0 ? sqrt(var) * us : 0.0,
            h->ads_interval_min * us, h->ads_interval_max * us);
    fprintf(f, "  \"isr\": {");
    int first = 1;
    for (int v = 0; v < 64; ++v) {
        if (!h->isr_count[v]) continue;
        const char *name = vector_name(v);
        fprintf(f, "%s\n    \"%d\": {\"name\": \"%s\", \"count\": %llu, \"max_cycles\": %llu}", first ? "" : ",", v,
                name ? name : "?", (unsigned long long)h->isr_count[v], (unsigned long long)h->isr_max_cycles[v]);
        first = 0;
    }
    fprintf(f, "\n  }\n}\n");
    return fclose(f);
}
