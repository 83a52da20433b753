// tsa_simavr: run the firmware ELF, unmodified, on simavr's ATmega2560 with the rig.
//
//   tsa_simavr --elf build/tsa_bench.elf --pty /tmp/x/tty --plant /tmp/x/plant.sock
//              [--summary out.json] [--lead-ms 1000] [--host-gone-ms 4000]
//              [--realtime FACTOR] [--max-seconds S] [--cs5513-conversion-us 19125]
//
// Contract. Opens the pty (uart_bridge), connects to the plant, then holds the AVR in
// reset until the plant sends 'G' (the host has the port open: like the DTR reset of
// a Mega). Pacing: device time never runs more than --lead-ms past the device time of
// the host's last byte, unless the host has been silent for --host-gone-ms of wall
// time (then it runs free, so the firmware's watchdog can trip); with --realtime it
// also never runs ahead of wall time x FACTOR. Output the host has not read stalls
// the AVR (back-pressure) until the host is gone. Stops on SIGINT/SIGTERM, when the
// plant hangs up, when the firmware crashes, or after --max-seconds of device time;
// then writes the JSON summary (summary.c) and exits 0, or 3 after a crash, 4 when
// the plant connection was lost, 2 on a usage or set-up error.
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <sim_avr.h>
#include <sim_elf.h>

#include "harness.h"
#include "plant_link.h"
#include "rig_map.h"
#include "summary.h"

static volatile sig_atomic_t g_stop = 0;
static void on_signal(int sig) { g_stop = sig; }

static struct harness H;

double harness_time_s(const struct harness *h) { return (double)h->avr->cycle / HZ_CPU; }

static double wall_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void usage(const char *msg) {
    fprintf(stderr, "tsa_simavr: %s\nusage: tsa_simavr --elf FILE --pty PATH --plant SOCKET [--summary FILE]\n"
                    "  [--lead-ms MS] [--host-gone-ms MS] [--realtime FACTOR] [--max-seconds S]\n"
                    "  [--cs5513-conversion-us US]\n", msg);
    exit(2);
}

int main(int argc, char **argv) {
    const char *elf = NULL, *pty = NULL, *plant_path = NULL, *summary_path = NULL;
    double lead_ms = 1000, gone_ms = 4000, realtime = 0, max_s = 0, cs_conv_us = 19125;
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
        else usage("unknown option");
    }
    if (!elf || !pty || !plant_path) usage("--elf, --pty and --plant are required");
    if (lead_ms <= 0 || gone_ms <= 0 || cs_conv_us <= 0 || realtime < 0 || max_s < 0)
        usage("times and factors must be positive");

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
    H.heater_supply_V = 12.0;
    H.moving_window_cycles = (uint64_t)(0.02 * HZ_CPU);

    char err[256];
    if (uart_bridge_attach(&H, pty, err, sizeof err) < 0) {
        fprintf(stderr, "tsa_simavr: %s\n", err);
        return 2;
    }
    drive_attach(&H);
    ads1115_attach(&H, RIG_ADS1115_ADDRESS);
    cs5513_attach(&H, cs_conv_us);
    isr_timing_attach(&H);

    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
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

    const uint64_t lead = (uint64_t)(lead_ms * 1e-3 * HZ_CPU);
    const uint64_t slice = (uint64_t)(0.0005 * HZ_CPU);
    const double wall0 = wall_s();
    int crashed = 0;
    while (!g_stop) {
        size_t pending = uart_bridge_service(&H, 0);
        drive_check_interlock(&H);
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
        while (H.avr->cycle < target) {
            const int state = avr_run(H.avr);
            if (state == cpu_Done || state == cpu_Crashed) break;
            if (H.avr->pc == 0) H.resets++;  // back at the reset vector: watchdog or a stray jump
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
    if (summary_path && summary_write(&H, summary_path, elf, reason, crashed, wall_s() - wall0) < 0)
        fprintf(stderr, "tsa_simavr: cannot write summary %s\n", summary_path);
    plant_close(H.plant);
    uart_bridge_close();
    unlink(pty);
    if (crashed) fprintf(stderr, "tsa_simavr: firmware crashed at pc 0x%05x after %.6f s\n", H.avr->pc,
                         harness_time_s(&H));
    if (crashed) return 3;
    return H.error[0] ? 4 : 0;
}
