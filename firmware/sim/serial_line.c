// The wire between the Mega's USB-serial chip and UART0, when the two ends may run at
// different baud rates (the host's end is whatever rate it set on the pty).
//
// Contract. serial_line_host_baud() reads the rate the host set on its end of the pty:
// TCGETS2 on the master returns the slave's termios (Linux), c_ospeed holding any rate
// (pyserial sets 250000 through BOTHER). serial_line_carry() is what a receiver at
// rx_baud decodes from n 8N1 frames sent back to back at tx_baud, the line idle (high)
// before and after: it finds a falling edge, samples the start bit at its middle (high:
// a false start, look again), the 8 data bits LSB first and the stop bit at their
// middles by its own clock, and looks for the next falling edge from the stop bit's
// middle on, as a UART receiver does. At equal rates this is the identity; up to about
// +-5 % apart (the stop bit's middle still inside the sender's stop bit) it still is;
// further apart the bytes come out garbled, lost or multiplied, as on a real line. A
// stop bit read low (a framing error) still yields its byte; FE is not emulated.
#define _GNU_SOURCE
#include <asm/termbits.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/ioctl.h>

#include "harness.h"

double serial_line_host_baud(int master_fd) {
    struct termios2 t;
    if (ioctl(master_fd, TCGETS2, &t) < 0) return 0.0;
    return (double)t.c_ospeed;
}

// The line level at time t (in sender bit times from the first start bit).
static int level(const uint8_t *in, size_t n, double t) {
    if (t < 0) return 1;
    const size_t k = (size_t)t, frame = k / 10, bit = k % 10;
    if (frame >= n) return 1;
    if (bit == 0) return 0;
    if (bit == 9) return 1;
    return (in[frame] >> (bit - 1)) & 1;
}

size_t serial_line_carry(const uint8_t *in, size_t n, double tx_baud, double rx_baud, uint8_t *out) {
    if (tx_baud <= 0 || rx_baud <= 0) return 0;
    const double r = tx_baud / rx_baud;  // one receiver bit time in sender bit times
    const double end = 10.0 * (double)n;
    size_t m = 0;
    double t = 0.0;
    for (;;) {
        // The next falling edge at or after t: a sender bit boundary k with bit k-1 high, bit k low.
        double k = t <= 0 ? 0.0 : (double)(size_t)t + ((double)(size_t)t < t ? 1.0 : 0.0);
        while (k < end && !(level(in, n, k - 0.5) == 1 && level(in, n, k + 0.5) == 0)) k += 1.0;
        if (k >= end) return m;
        if (level(in, n, k + 0.5 * r)) {  // a glitch, not a start bit
            t = k + 0.5 * r;
            continue;
        }
        uint8_t byte = 0;
        for (int i = 0; i < 8; ++i) byte |= (uint8_t)(level(in, n, k + (1.5 + i) * r) << i);
        out[m++] = byte;
        t = k + 9.5 * r;
    }
}
