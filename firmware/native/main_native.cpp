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
// Sends BOOT at once; exits when stdin closes. The IDENTITY has the SIMULATED flag and
// SIM_SET_LOAD changes the (crude) simulated sensors. Sensors: position counts fall
// with twist, resistance counts rise with it, both steady at rest.
#include <errno.h>
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

}  // namespace

int main(int argc, char** argv) {
    double speed = 1.0;
    bool virtual_time = false;
    for (int i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--speed") && i + 1 < argc) {
            speed = atof(argv[++i]);
        } else if (!strcmp(argv[i], "--virtual")) {
            virtual_time = true;
        } else if (!strcmp(argv[i], "--cs5513-us") && i + 1 < argc) {
            g_board.resistance_latency_us = static_cast<uint32_t>(atol(argv[++i]));
        } else {
            fprintf(stderr, "usage: %s [--speed X | --virtual] [--cs5513-us US]\n", argv[0]);
            return 2;
        }
    }
    const uint64_t wd_us = static_cast<uint64_t>(cfg::WATCHDOG_MS) * 1000ULL;
    g_board.reason = proto::boot_reason::EXTERNAL_RESET;
    g_board.tx_ring_size = 4096;
    g_dev.set_sim_load_handler(on_load, 0);
    g_dev.boot();

    uint8_t in[1024];
    size_t in_len = 0;
    bool eof = false;
    const uint64_t wall0 = wall_us();
    uint64_t last_host_dev_us = 0, last_host_wall = wall0;
    uint8_t out[4096];
    for (;;) {
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
