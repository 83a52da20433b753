// tsa_simavr: the bench harness around the unmodified firmware ELF in simavr.
//
// Contract. One `struct harness` holds the simulated ATmega2560 and every emulated
// part of the rig wired to it (hal/pins.h is the wiring). Each part is a module with
// an *_attach() that registers its simavr IRQ hooks, a *_reset() for when the AVR
// resets (the parts themselves keep their state; simavr drops every cycle timer), and
// figures it leaves in `struct harness` for the JSON summary. Times are AVR cycles
// (16 MHz) unless a name says otherwise. Plant values come from the host's Python plant
// over plant_link (one source of plant truth); nothing here models the strings.
#pragma once
#include <stdint.h>
#include <stdio.h>

#include <sim_avr.h>

#define HZ_CPU 16000000.0
#define HEATER_MAX_PERIODS 32
#define MAX_RESETS 64

struct plant_link;

// A4988 + heater + current source: what the power stages see.
struct drive_state {
    int32_t steps;                 // signed step count (DIR high = +1), enabled pulses only
    uint64_t steps_total;          // every enabled rising edge
    uint64_t steps_while_disabled; // rising edges with /ENABLE high (the motor ignores them)
    uint64_t steps_backdriven;     // steps the loaded strings turned a released motor back
    int64_t steps_home_shift;      // steps the translator's restart at Home moved the rotor (brown-outs)
    uint64_t pulse_width_violations;   // STEP high or low < 1 us
    uint64_t dir_setup_violations;     // DIR changed < 200 ns before a STEP rising edge
    uint64_t dir_hold_violations;      // DIR changed < 200 ns after a STEP rising edge
    uint64_t interlock_violations;     // heater gate driven while the sense current is on
    uint64_t min_step_high_cycles, min_step_low_cycles;
    uint64_t last_step_rise, last_step_fall, last_dir_change;
    uint64_t last_step_cycle;      // for "moving"
    int step_level, dir_level, enabled;
    int interlock_active;
    int sense_on;                  // AD8276 current source enable (PC3)
    uint64_t sense_on_cycle, last_sense_off_cycle;
    uint64_t last_disable_cycle, disables;
};

struct harness {
    avr_t *avr;
    struct plant_link *plant;
    struct drive_state drive;
    double backdrive_steps_per_s;
    uint64_t moving_window_cycles;  // a step within this window = motor moving
    uint64_t t3_zero_cycle;         // when the firmware started Timer3 (its microsecond clock)
    // figures gathered by the modules
    uint64_t uart_rx_bytes, uart_tx_bytes, uart_rx_overruns, uart_rx_held_before_rxen;
    uint64_t uart_tx_first_cycle, uart_tx_last_cycle;
    uint64_t uart_tx_longest_burst_bytes, uart_tx_longest_burst_cycles;  // back-to-back bytes
    uint64_t uart_cycles_per_byte_fixes;
    uint64_t twi_status_fixes, twi_transactions, twi_naks;
    uint64_t twi_starts, twi_stops, twi_bytes, twi_naks_injected, twi_stretched_bytes;
    uint64_t twi_stuck_events, twi_manual_clocks, twi_releases;
    uint64_t ads_conversions, ads_alerts, ads_rdy_pulses, ads_rdy_pulses_cut, ads_unread, cs_conversions, cs_words_read,
        cs_partial_reads;
    double ads_read_latency_max_us;  // continuous mode: conversion end to the read of its result
    uint64_t cs_od_words, cs_sclk_violations;
    uint64_t plant_queries;
    uint64_t resets;               // hardware resets after power-on (DTR, watchdog)
    uint64_t app_starts;           // the application's reset vector reached (incl. restarts)
    int n_reset_log;
    double reset_t_s[MAX_RESETS];
    char reset_cause[MAX_RESETS][24];
    // heater: stretches of heating with their mean duty
    uint64_t heater_periods;
    double heater_period_start_s[HEATER_MAX_PERIODS], heater_period_end_s[HEATER_MAX_PERIODS];
    double heater_period_duty[HEATER_MAX_PERIODS];
    double heater_last_off_s;
    // sample-period jitter: intervals between ADS1115 conversion starts
    uint64_t ads_last_start;
    uint64_t ads_intervals;
    double ads_interval_sum, ads_interval_sq_sum, ads_interval_min, ads_interval_max;
    // ISR durations
    uint64_t isr_max_cycles[64], isr_count[64], isr_entered[64];
    int isr_active[64];
    char error[256];
};

double harness_time_s(const struct harness *h);
// The firmware's own clock (Timer3 microseconds since it started) at a cycle.
double harness_app_us(const struct harness *h, uint64_t cycle);
int harness_motor_moving(const struct harness *h);
double harness_heater_duty(const struct harness *h);

// Modules (see each .c for its contract).
void wiring_attach(struct harness *h);
void wiring_pull(struct harness *h, char port, int bit, int level);
void wiring_release(struct harness *h, char port, int bit);
int wiring_level(const struct harness *h, char port, int bit);
void wiring_reapply(struct harness *h);
void drive_attach(struct harness *h, int enable_pull_up);
void drive_check_interlock(struct harness *h);  // also called every slice (Timer2 has no IRQ)
void drive_tick(struct harness *h);
void drive_reset(struct harness *h);
// A brown-out: the A4988's translator restarts at Home under its own UVLO, the rotor
// moving to the nearest Home position of its electrical cycle.
void drive_brown_out(struct harness *h);
void ads1115_attach(struct harness *h, uint8_t address7, double rate_error, FILE *trace);
void ads1115_reset(struct harness *h);
int ads1115_add_rdy_cut(const char *spec);  // before ads1115_attach; -1 on a bad spec
int twi_bus_add_fault(const char *spec, char *err, size_t errlen);
void twi_bus_attach(struct harness *h);
void twi_bus_reset(struct harness *h);
int twi_bus_nack_now(void);
int twi_bus_nack_config(void);  // 1: NACK this byte written to the ADS1115's config register
uint64_t twi_bus_byte_cycles(void);
void cs5513_attach(struct harness *h, double conversion_us);
void cs5513_reset(struct harness *h);
void isr_timing_attach(struct harness *h);
int uart_bridge_attach(struct harness *h, const char *pty_link, char *err, size_t errlen);
// Moves host bytes in and device bytes out; returns bytes still waiting to be sent to the host.
size_t uart_bridge_service(struct harness *h, int wait_ms);
uint64_t uart_bridge_last_rx_cycle(void);   // for pacing: the host's last byte or the last reset
uint64_t uart_bridge_host_rx_cycle(void);   // the host's last byte
double uart_bridge_last_rx_wall(void);
// Counts as host activity for pacing (a reset: let the bootloader and the boot run).
void uart_bridge_note_activity(uint64_t cycle);
void uart_bridge_discard_output(void);
void uart_bridge_reset(struct harness *h);
void uart_bridge_close(void);
void twi_quirks_apply(struct harness *h);
