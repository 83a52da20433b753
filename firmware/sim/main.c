// tsa_simavr: run the firmware ELF, unmodified, on simavr's ATmega2560 with the rig.
//
//   tsa_simavr --elf build/tsa_bench.elf --pty /tmp/x/tty --plant /tmp/x/plant.sock
//              [--summary out.json] [--lead-ms 1000] [--host-gone-ms 4000]
//              [--realtime FACTOR] [--max-seconds S] [--cs5513-conversion-us 19125]
//              [--bootloader ELF|none] [--enable-pull down|up] [--backdrive-steps-per-s N]
//              [--twi-fault SPEC]... [--ads-rate-error X] [--trace FILE] [--hang-at S]
//              [--hang-masked 0|1] [--rdy-cut T0[:T1]]...
//
// Contract. Opens the pty (uart_bridge), connects to the plant, then holds the AVR in
// reset until the plant sends 'G' (the host has the port open: like the DTR reset of
// a Mega). Power-on: SRAM holds random bytes (as a real chip's does), MCUSR says PORF.
// With --bootloader (the launcher passes build/sim_boot_stock.elf; sim/boot/) every
// reset runs it first from 0x3E000, as BOOTRST makes the Mega do: ~1 s with the
// application's pins floating, MCUSR handled as that bootloader does. SIGUSR1 is the
// DTR pulse of a host opening the port again (external reset, EXTRF); SIGUSR2 a
// brown-out (BORF, SRAM kept, the A4988's translator back at Home); a watchdog reset
// comes from simavr's WDT. After any reset the rig's parts carry on (they are not reset)
// and re-arm their timers. --hang-at S makes the main loop hang at S s of device time
// (a `rjmp .` loop entered with interrupts enabled, outside any ISR), as a firmware bug
// would, to exercise the watchdog; with --hang-masked 1 the loop runs with interrupts
// masked (a hang inside an ISR or an atomic block). The watchdog in interrupt-and-reset
// mode resets the chip when its interrupt was not served before the next time-out, as
// the datasheet says (simavr 1.6 would raise the interrupt forever). Pacing: device time never runs more than --lead-ms past the device time of
// the host's last byte (or of the last reset), unless the host has been silent for
// --host-gone-ms of wall time (then it runs free, so the firmware's watchdog can trip);
// with --realtime it also never runs ahead of wall time x FACTOR. Output the host has
// not read stalls the AVR (back-pressure) until the host is gone. Stops on
// SIGINT/SIGTERM, when the plant hangs up, when the firmware crashes, or after
// --max-seconds of device time; then writes the JSON summary (summary.c) and exits 0,
// or 3 after a crash, 4 when the plant connection was lost, 2 on a usage or set-up error.
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <avr_watchdog.h>
#include <sim_avr.h>
#include <sim_core.h>
#include <sim_elf.h>

#include "harness.h"
#include "plant_link.h"
#include "rig_map.h"
#include "summary.h"

#define BOOT_PC 0x3E000     // BOOTRST: the reset vector of the Mega's 8 KB boot section
#define HANG_PC 0x3DFFE     // an erased flash word just below it, where --hang-at loops
#define BOOT_LEAD_S 1.5     // pacing allowance after a reset (bootloader wait + boot)

static volatile sig_atomic_t g_stop = 0;
static volatile sig_atomic_t g_dtr = 0;
static volatile sig_atomic_t g_brown = 0;
static void on_signal(int sig) { g_stop = sig; }
static void on_usr1(int sig) {
    (void)sig;
    g_dtr = 1;
}
static void on_usr2(int sig) {
    (void)sig;
    g_brown = 1;
}

static struct harness H;

double harness_time_s(const struct harness *h) { return (double)h->avr->cycle / HZ_CPU; }

double harness_app_us(const struct harness *h, uint64_t cycle) {
    return cycle >= h->t3_zero_cycle ? (double)(cycle - h->t3_zero_cycle) / (HZ_CPU / 1e6) : 0.0;
}

static double wall_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void usage(const char *msg) {
    fprintf(stderr, "tsa_simavr: %s\nusage: tsa_simavr --elf FILE --pty PATH --plant SOCKET [--summary FILE]\n"
                    "  [--lead-ms MS] [--host-gone-ms MS] [--realtime FACTOR] [--max-seconds S]\n"
                    "  [--cs5513-conversion-us US] [--bootloader ELF|none] [--enable-pull down|up]\n"
                    "  [--backdrive-steps-per-s N] [--twi-fault SPEC]... [--ads-rate-error X]\n"
                    "  [--trace FILE] [--hang-at S] [--hang-masked 0|1] [--rdy-cut T0[:T1]]...\n", msg);
    exit(2);
}

// Timer3 started: the firmware's microsecond clock counts from here.
static uint8_t g_tccr3b;  // the value before this write (simavr's timer handler runs first)
static void on_tccr3b(struct avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param) {
    (void)addr;
    (void)param;
    if ((v & 7) && !(g_tccr3b & 7)) H.t3_zero_cycle = avr->cycle;
    g_tccr3b = v;
}

// A timer far in the future: simavr drops every cycle timer when the AVR resets, so
// when this one is gone the AVR has just been reset.
static avr_cycle_count_t canary(struct avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)avr;
    (void)param;
    return when + (1ULL << 50);
}

static void arm_canary(void) { avr_cycle_timer_register(H.avr, 1ULL << 50, canary, NULL); }

static void log_reset(const char *cause) {
    if (H.n_reset_log < MAX_RESETS) {
        H.reset_t_s[H.n_reset_log] = harness_time_s(&H);
        snprintf(H.reset_cause[H.n_reset_log], sizeof H.reset_cause[0], "%s", cause);
        H.n_reset_log++;
    }
}

// Everything after a reset: the rig's wiring is back on the floating pins, the parts
// re-arm their timers, the host's pacing allows for the bootloader.
static avr_watchdog_t *g_wd;        // simavr's WDT (the struct is in its public header)
static uint64_t g_wd_raised_cycle;  // when its interrupt became pending; 0 = not pending

static void on_wd_pending(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    (void)param;
    if (!value)
        g_wd_raised_cycle = 0;
    else if (!g_wd_raised_cycle)
        g_wd_raised_cycle = H.avr->cycle ? H.avr->cycle : 1;
}

static void find_watchdog(void) {
    for (avr_io_t *io = H.avr->io_port; io; io = io->next)
        if (io->kind && !strcmp(io->kind, "watchdog")) g_wd = (avr_watchdog_t *)io;
    if (g_wd) avr_irq_register_notify(g_wd->watchdog.irq + AVR_INT_IRQ_PENDING, on_wd_pending, NULL);
}

static void after_reset(const char *cause) {
    log_reset(cause);
    g_tccr3b = 0;
    g_wd_raised_cycle = 0;
    wiring_reapply(&H);
    uart_bridge_reset(&H);
    ads1115_reset(&H);
    twi_bus_reset(&H);
    cs5513_reset(&H);
    drive_reset(&H);
    arm_canary();
    uart_bridge_note_activity(H.avr->cycle + (uint64_t)(BOOT_LEAD_S * HZ_CPU));
}

static void reset_avr(uint8_t mcusr_flag, const char *cause) {
    avr_reset(H.avr);
    H.avr->data[REG_MCUSR] |= (uint8_t)(1u << mcusr_flag);
    after_reset(cause);
}

static int load_bootloader(const char *path) {
    elf_firmware_t boot;
    memset(&boot, 0, sizeof boot);
    if (elf_read_firmware(path, &boot) != 0 || boot.flashbase != BOOT_PC || !boot.flash ||
        boot.flashbase + boot.flashsize > H.avr->flashend + 1)
        return -1;
    memcpy(H.avr->flash + boot.flashbase, boot.flash, boot.flashsize);
    H.avr->reset_pc = BOOT_PC;
    return 0;
}

int main(int argc, char **argv) {
    const char *elf = NULL, *pty = NULL, *plant_path = NULL, *summary_path = NULL, *boot = NULL, *trace_path = NULL;
    double lead_ms = 1000, gone_ms = 4000, realtime = 0, max_s = 0, cs_conv_us = 19125, ads_rate_error = 0;
    double backdrive = 16000, hang_at = -1;
    int hang_masked = 0;
    int enable_pull_up = 0;
    char err[256];
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        if (i + 1 >= argc) usage("every option takes a value");
        const char *v = argv[++i];
        if (!strcmp(a, "--elf")) elf = v;
        else if (!strcmp(a, "--pty")) pty = v;
        else if (!strcmp(a, "--plant")) plant_path = v;
        else if (!strcmp(a, "--summary")) summary_path = v;
        else if (!strcmp(a, "--lead-ms")) lead_ms = atof(v);
        else if (!strcmp(a, "--host-gone-ms")) gone_ms = atof(v);
        else if (!strcmp(a, "--realtime")) realtime = atof(v);
        else if (!strcmp(a, "--max-seconds")) max_s = atof(v);
        else if (!strcmp(a, "--cs5513-conversion-us")) cs_conv_us = atof(v);
        else if (!strcmp(a, "--bootloader")) boot = strcmp(v, "none") ? v : NULL;
        else if (!strcmp(a, "--enable-pull")) {
            if (strcmp(v, "down") && strcmp(v, "up")) usage("--enable-pull takes down or up");
            enable_pull_up = !strcmp(v, "up");
        } else if (!strcmp(a, "--backdrive-steps-per-s")) backdrive = atof(v);
        else if (!strcmp(a, "--twi-fault")) {
            if (twi_bus_add_fault(v, err, sizeof err) < 0) usage(err);
        } else if (!strcmp(a, "--ads-rate-error")) ads_rate_error = atof(v);
        else if (!strcmp(a, "--rdy-cut")) {
            if (ads1115_add_rdy_cut(v) < 0) usage("--rdy-cut takes T0[:T1] (s, T1 >= T0), at most 4 times");
        }
        else if (!strcmp(a, "--trace")) trace_path = v;
        else if (!strcmp(a, "--hang-at")) hang_at = atof(v);
        else if (!strcmp(a, "--hang-masked")) hang_masked = atoi(v) != 0;
        else usage("unknown option");
    }
    if (!elf || !pty || !plant_path) usage("--elf, --pty and --plant are required");
    if (lead_ms <= 0 || gone_ms <= 0 || cs_conv_us <= 0 || realtime < 0 || max_s < 0 || backdrive < 0 ||
        ads_rate_error < -0.5 || ads_rate_error > 0.5)
        usage("times and factors must be positive (--ads-rate-error within +-0.5)");

    elf_firmware_t fw;
    memset(&fw, 0, sizeof fw);
    if (elf_read_firmware(elf, &fw) != 0) {
        fprintf(stderr, "tsa_simavr: cannot read firmware ELF %s\n", elf);
        return 2;
    }
    H.avr = avr_make_mcu_by_name("atmega2560");
    if (!H.avr) {
        fprintf(stderr, "tsa_simavr: simavr has no atmega2560 core\n");
        return 2;
    }
    avr_init(H.avr);
    H.avr->log = LOG_ERROR;
    avr_load_firmware(H.avr, &fw);
    H.avr->frequency = (uint32_t)HZ_CPU;
    H.moving_window_cycles = (uint64_t)(0.02 * HZ_CPU);
    H.backdrive_steps_per_s = backdrive;
    if (boot && load_bootloader(boot) < 0) {
        fprintf(stderr, "tsa_simavr: cannot load the bootloader %s (an ELF linked at 0x%X)\n", boot, BOOT_PC);
        return 2;
    }
    FILE *trace = NULL;
    if (trace_path && !(trace = fopen(trace_path, "w"))) {
        fprintf(stderr, "tsa_simavr: cannot write the trace %s\n", trace_path);
        return 2;
    }

    if (uart_bridge_attach(&H, pty, err, sizeof err) < 0) {
        fprintf(stderr, "tsa_simavr: %s\n", err);
        return 2;
    }
    wiring_attach(&H);
    drive_attach(&H, enable_pull_up);
    ads1115_attach(&H, RIG_ADS1115_ADDRESS, ads_rate_error, trace);
    twi_bus_attach(&H);
    cs5513_attach(&H, cs_conv_us);
    isr_timing_attach(&H);
    avr_register_io_write(H.avr, REG_TCCR3B, on_tccr3b, NULL);

    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    signal(SIGUSR1, on_usr1);
    signal(SIGUSR2, on_usr2);
    signal(SIGPIPE, SIG_IGN);
    H.plant = plant_connect(plant_path, err, sizeof err);
    if (!H.plant) {
        fprintf(stderr, "tsa_simavr: %s\n", err);
        return 2;
    }
    fprintf(stdout, "tsa_simavr: ready on %s\n", pty);
    fflush(stdout);
    const char *reason = "stopped by signal";
    if (plant_wait_start(H.plant) < 0) {
        reason = "plant hung up before start";
        strcpy(H.error, reason);
        g_stop = -1;
    }
    find_watchdog();
    // Power-on: SRAM content is whatever the cells settled to.
    srand(0x7A5B);
    for (uint32_t a = 0x200; a <= H.avr->ramend; ++a) H.avr->data[a] = (uint8_t)(rand() >> 7);
    reset_avr(MCUSR_PORF, "power_on");

    const uint64_t lead = (uint64_t)(lead_ms * 1e-3 * HZ_CPU);
    const uint64_t slice = (uint64_t)(0.0005 * HZ_CPU);
    uint64_t hang_cycle = hang_at >= 0 ? (uint64_t)(hang_at * HZ_CPU) : UINT64_MAX;
    const double wall0 = wall_s();
    int crashed = 0;
    while (!g_stop) {
        if (g_dtr) {
            g_dtr = 0;
            H.resets++;
            reset_avr(MCUSR_EXTRF, "external");
        }
        if (g_brown) {  // the supply dipped: SRAM kept, BORF (the stock bootloader clears it)
            g_brown = 0;
            H.resets++;
            drive_brown_out(&H);
            reset_avr(MCUSR_BORF, "brown_out");
        }
        size_t pending = uart_bridge_service(&H, 0);
        drive_check_interlock(&H);
        drive_tick(&H);
        const double now_wall = wall_s();
        const int host_gone = now_wall - uart_bridge_last_rx_wall() > gone_ms * 1e-3;
        uint64_t limit = host_gone ? UINT64_MAX : uart_bridge_last_rx_cycle() + lead;
        if (realtime > 0) {
            const uint64_t rt = (uint64_t)((now_wall - wall0) * realtime * HZ_CPU);
            if (rt < limit) limit = rt;
        }
        if (host_gone && pending > (1u << 20)) uart_bridge_discard_output();
        const int stalled = pending > 16384 && !host_gone;
        if (H.avr->cycle >= limit || stalled) {
            uart_bridge_service(&H, 2);
            continue;
        }
        uint64_t target = H.avr->cycle + slice;
        if (target > limit) target = limit;
        if (target > hang_cycle && H.avr->cycle < hang_cycle) target = hang_cycle;
        while (H.avr->cycle < target) {
            const avr_flashaddr_t pc_before = H.avr->pc;
            const int state = avr_run(H.avr);
            if (state == cpu_Done || state == cpu_Crashed) break;
            // simavr reset the AVR (watchdog)? Only worth asking (a walk of the timer list)
            // when the PC has just arrived at the reset vector.
            if (H.avr->pc - H.avr->reset_pc < 16 && pc_before - H.avr->reset_pc >= 16 &&
                !avr_cycle_timer_status(H.avr, canary, NULL)) {
                H.resets++;
                after_reset(H.avr->data[REG_MCUSR] & (1u << MCUSR_WDRF) ? "watchdog" : "unknown");
            }
            if (H.avr->pc == 0 && pc_before != 0) H.app_starts++;
        }
        if (H.avr->cycle >= hang_cycle && hang_cycle != UINT64_MAX) {
            if (!H.avr->sreg[S_I]) {
                hang_cycle = H.avr->cycle + 1;  // inside an ISR or an atomic block: the main loop hangs, not that
            } else {
                H.avr->flash[HANG_PC] = 0xFF;  // rjmp .-2 (0xCFFF): loops on itself
                H.avr->flash[HANG_PC + 1] = 0xCF;
                H.avr->pc = HANG_PC;
                if (hang_masked) avr_sreg_set(H.avr, S_I, 0);
                log_reset(hang_masked ? "hang_injected_masked" : "hang_injected");
                hang_cycle = UINT64_MAX;
            }
        }
        // Interrupt-and-reset mode: an interrupt not served by the next time-out resets.
        if (g_wd && g_wd_raised_cycle && avr_regbit_get(H.avr, g_wd->wde) &&
            H.avr->cycle - g_wd_raised_cycle >= g_wd->cycle_count) {
            H.resets++;
            g_wd->reset_context.avr_run = H.avr->run;  // simavr's own path: WDE and WDRF set, fastest period
            g_wd->reset_context.wdrf = 1;
            reset_avr(MCUSR_WDRF, "watchdog");
        }
        if (H.avr->state == cpu_Crashed) {
            crashed = 1;
            reason = "firmware crashed";
            break;
        }
        if (H.avr->state == cpu_Done) {
            reason = H.error[0] ? H.error : "firmware stopped (cpu_Done)";
            break;
        }
        if (max_s > 0 && harness_time_s(&H) >= max_s) {
            reason = "reached --max-seconds";
            break;
        }
    }
    for (int i = 0; i < 20 && uart_bridge_service(&H, 5); ++i) {
    }
    if (g_stop > 0) reason = g_stop == SIGINT ? "SIGINT" : "SIGTERM";
    drive_check_interlock(&H);
    if (summary_path && summary_write(&H, summary_path, elf, reason, crashed, wall_s() - wall0) < 0)
        fprintf(stderr, "tsa_simavr: cannot write summary %s\n", summary_path);
    if (trace) fclose(trace);
    plant_close(H.plant);
    uart_bridge_close();
    unlink(pty);
    if (crashed) fprintf(stderr, "tsa_simavr: firmware crashed at pc 0x%05x after %.6f s\n", H.avr->pc,
                         harness_time_s(&H));
    if (crashed) return 3;
    return H.error[0] ? 4 : 0;
}
