// Native stdio device: the real firmware core (fw::Device) on the FakeBoard, speaking
// the binary protocol on stdin/stdout, for conformance tests against the simulated
// device (host/tsa_bench/sim/device.py). Not part of the AVR build.
//
// Build:
//   g++ -std=c++11 -O2 -Ifirmware -Ifirmware/core -Ifirmware/tests firmware/core/*.cpp
//       firmware/tests/fake_board.cpp firmware/native/main_native.cpp
//       -o firmware/build/tsa_bench_native        (one line, from the repository root)
// Run:  tsa_bench_native [--speed X | --virtual] [--cs5513-us US]
//   --speed X  device time = wall time x X (default 1).
//   --virtual  device time runs as fast as possible while the host is quiet, but never
//              more than an eighth of a watchdog period past the last byte from the host, unless
//              the host has been silent for two watchdog periods of wall time (gone, not
//              slow: then the watchdog fires), as `tsa-bench sim-serve` paces itself.
//   --cs5513-us US  a resistance word takes US after arming (default 0: at once; 19125 is
//              the CS5513 at its slowest on-chip oscillator, DS337: CLK/612 at 32 kHz).
//   --as-hardware  the IDENTITY has no SIMULATED flag and SIM_SET_LOAD is unknown, as on
//              the Mega (a rehearsal rig: the host asks its operator what a real rig asks).
//   --control-fd FD  lines read from FD act on the board as a person or the USB bridge
//              would: "reset" = an external reset (the DTR pulse when a port opens: the core
//              restarts, the position kept when its record is valid and the motor held),
//              "load G" = G grams now hang on the TSA.
// Sends BOOT at once; exits when stdin closes. Without --as-hardware the IDENTITY has the
// SIMULATED flag and SIM_SET_LOAD changes the (crude) simulated sensors. Sensors: position
// counts fall with twist and load, resistance counts rise with twist, both steady at rest.
#include <errno.h>
#include <new>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "config.h"
#include "device.h"
#include "fake_board.h"

namespace {

uint64_t wall_us() {
    timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<uint64_t>(ts.tv_sec) * 1000000ULL + static_cast<uint64_t>(ts.tv_nsec / 1000);
}

uint32_t g_load_mg = 500000;

void on_load(void*, uint32_t load_mg) { g_load_mg = load_mg; }

void update_sensors(fw::FakeBoard& b) {
    int32_t pos = b.position;
    int32_t counts = 20000 - pos / 40 - static_cast<int32_t>(g_load_mg / 100000);
    b.position_counts = static_cast<int16_t>(counts < -32768 ? -32768 : counts > 32767 ? 32767 : counts);
    b.resistance_counts = 300000 + pos / 4;
}

bool write_all(const uint8_t* p, size_t n) {
    while (n > 0) {
        ssize_t w = write(STDOUT_FILENO, p, n);
        if (w < 0) {
            if (errno == EINTR || errno == EAGAIN) continue;
            return false;
        }
        p += w;
        n -= static_cast<size_t>(w);
    }
    return true;
}

fw::FakeBoard g_board;
fw::Device g_dev(g_board);
bool g_as_hardware = false;

// An external reset: SRAM (the board's position record) survives, the core starts anew.
void external_reset() {
    g_board.kept_valid = g_board.record_valid && g_board.motor_enabled;
    g_board.kept_steps = g_board.record_steps;
    g_board.reason = proto::boot_reason::EXTERNAL_RESET;
    g_dev.~Device();
    new (&g_dev) fw::Device(g_board);
    if (!g_as_hardware) g_dev.set_sim_load_handler(on_load, 0);
    g_dev.boot();
}

// Lines from the control descriptor (see the header); a partial line waits for its end.
void read_control(int fd, char* line, size_t& len) {
    pollfd pfd = {fd, POLLIN, 0};
    if (fd < 0 || poll(&pfd, 1, 0) <= 0) return;
    ssize_t r = read(fd, line + len, 127 - len);
    if (r <= 0) return;
    len += static_cast<size_t>(r);
    char* nl;
    while ((nl = static_cast<char*>(memchr(line, '\n', len))) != 0) {
        *nl = 0;
        if (!strcmp(line, "reset")) {
            external_reset();
        } else if (!strncmp(line, "load ", 5)) {
            double g = atof(line + 5);
            if (g >= 0 && g < 4e6) g_load_mg = static_cast<uint32_t>(g * 1000.0 + 0.5);
        }
        size_t used = static_cast<size_t>(nl - line) + 1;
        memmove(line, nl + 1, len - used);
        len -= used;
    }
    if (len >= 127) len = 0;  // an overlong line: dropped
}

}  // namespace

int main(int argc, char** argv) {
    double speed = 1.0;
    bool virtual_time = false;
    int control_fd = -1;
    for (int i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--speed") && i + 1 < argc) {
            speed = atof(argv[++i]);
        } else if (!strcmp(argv[i], "--virtual")) {
            virtual_time = true;
        } else if (!strcmp(argv[i], "--cs5513-us") && i + 1 < argc) {
            g_board.resistance_latency_us = static_cast<uint32_t>(atol(argv[++i]));
        } else if (!strcmp(argv[i], "--as-hardware")) {
            g_as_hardware = true;
        } else if (!strcmp(argv[i], "--control-fd") && i + 1 < argc) {
            control_fd = atoi(argv[++i]);
        } else {
            fprintf(stderr, "usage: %s [--speed X | --virtual] [--cs5513-us US] [--as-hardware] "
                            "[--control-fd FD]\n", argv[0]);
            return 2;
        }
    }
    const uint64_t wd_us = static_cast<uint64_t>(cfg::WATCHDOG_MS) * 1000ULL;
    g_board.reason = g_as_hardware ? proto::boot_reason::POWER_ON : proto::boot_reason::EXTERNAL_RESET;
    g_board.tx_ring_size = 4096;
    if (!g_as_hardware) g_dev.set_sim_load_handler(on_load, 0);
    g_dev.boot();
    char control[128];
    size_t control_len = 0;

    uint8_t in[1024];
    size_t in_len = 0;
    bool eof = false;
    const uint64_t wall0 = wall_us();
    uint64_t last_host_dev_us = 0, last_host_wall = wall0;
    uint8_t out[4096];
    for (;;) {
        read_control(control_fd, control, control_len);
        // 1. host bytes
        if (!eof && in_len < sizeof in) {
            pollfd pfd = {STDIN_FILENO, POLLIN, 0};
            bool idle = g_board.rx_pending() == 0 && in_len == 0;
            int timeout_ms = idle && !virtual_time ? 1 : 0;
            if (poll(&pfd, 1, timeout_ms) > 0) {
                ssize_t r = read(STDIN_FILENO, in + in_len, sizeof in - in_len);
                if (r > 0) {
                    in_len += static_cast<size_t>(r);
                } else if (r == 0 || (errno != EINTR && errno != EAGAIN)) {
                    eof = true;
                }
            }
        }
        if (in_len > 0) {
            uint16_t took = g_board.host_write(in, static_cast<uint16_t>(in_len));
            memmove(in, in + took, in_len - took);
            in_len -= took;
            last_host_dev_us = g_board.now;
            last_host_wall = wall_us();
        }
        if (eof && in_len == 0 && g_board.rx_pending() == 0) break;

        // 2. time
        uint64_t target;
        if (virtual_time) {
            bool gone = wall_us() - last_host_wall > 2 * wd_us;
            uint64_t cap = last_host_dev_us + wd_us / 8;
            target = g_board.rx_pending() ? g_board.now : g_board.now + 1000;
            if (!gone && target > cap) target = cap > g_board.now ? cap : g_board.now;
            if (target == g_board.now && !gone) usleep(200);
        } else {
            target = static_cast<uint64_t>(static_cast<double>(wall_us() - wall0) * speed);
        }
        do {
            uint64_t dt = target - g_board.now;
            if (dt > 50) dt = 50;
            g_board.advance_us(dt);
            update_sensors(g_board);
            g_dev.poll();
        } while (g_board.now < target);

        // 3. device bytes
        uint32_t n;
        while ((n = g_board.take_tx(out, sizeof out)) > 0) {
            if (!write_all(out, n)) return 1;
        }
    }
    return 0;
}
