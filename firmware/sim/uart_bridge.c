// UART0 <-> a pseudo-terminal of the harness's own, at the real line rate.
//
// Contract. uart_bridge_attach() opens a pty pair, makes the slave raw, links the
// caller's path to it (a symlink, replaced if present) and keeps its own slave
// descriptor open, so a client may close and reopen the port without the master
// seeing EIO. Host bytes are fed to the AVR one per frame time (10 bit times for
// 8N1 at the configured baud), as a real line delivers them. simavr 1.6 quirks:
//  - its UART counts 11 bits per byte (a parity bit even when parity is off) and
//    computes the byte time only when UBRR is written, before the firmware sets U2X;
//    the bridge recomputes the byte time from the registers on every service call;
//  - its 64-byte RX FIFO with XON/XOFF hides overruns: the bridge ignores XON/XOFF
//    and, when a byte completes while two unread bytes already wait (the real
//    2-level receive buffer is full), drops it, counts an overrun and sets DOR0 in
//    UCSR0A until the firmware next reads UDR0, as the chip does;
//  - bytes arriving before RXEN0 is set would be dropped: the bridge holds them
//    until the receiver is enabled and counts them (the host should wait for BOOT).
// With usb_serial set the pty behaves as the Mega's USB-serial chip (the 16U2) does:
// the bridge keeps no slave open and watches the slave's opens and closes (inotify, in
// order, so a close and a reopen between two looks are both seen). An open while no
// one has the port open raises DTR: the auto-reset's edge, which
// uart_bridge_take_port_opened() reports once. While no host has the port open, the
// AVR's output is dropped (not held back). Bytes cross at the host's baud rate against
// the UART's (serial_line.c): a host at the wrong rate reads and sends garbage. Host
// bytes arriving while the receiver is off are lost, as on the chip.
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/inotify.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <avr_uart.h>

#include "harness.h"
#include "rig_map.h"

#define RING 65536

static struct {
    struct harness *h;
    avr_uart_t *uart;
    avr_irq_t *rx_irq;
    int master, slave;
    uint8_t rx[RING];
    size_t rx_head, rx_tail;    // host -> AVR
    uint8_t *tx;
    size_t tx_len, tx_cap;      // AVR -> host, not yet written
    int usb_serial;             // the Mega's USB-serial chip (see the contract)
    int ino;                    // usb_serial: inotify on the slave (opens and closes)
    int port_open, port_opened; // openers of the port now; an open from none since last asked
    uint8_t *wire;
    size_t wire_len, wire_cap;  // usb_serial: AVR bytes not yet carried over the line
    int pump_running;
    uint64_t last_rx_cycle;     // the host's last byte
    uint64_t activity_cycle;    // a reset: pace as if the host had just spoken
    double last_rx_wall;
    int held_counted;
    uint64_t burst_bytes, burst_start;
    avr_io_read_t udr_read;  // simavr's UDR0 read handler, wrapped
    void *udr_param;
} g;

static double wall_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static uint64_t bit_cycles(void) {
    avr_t *avr = g.h->avr;
    avr_uart_t *u = g.uart;
    const uint32_t ubrr = avr_regbit_get(avr, u->ubrrl) | (avr_regbit_get(avr, u->ubrrh) << 8);
    return (uint64_t)(ubrr + 1) * (avr_regbit_get(avr, u->u2x) ? 8 : 16);
}

static double uart_baud(void) { return HZ_CPU / (double)bit_cycles(); }

static uint64_t frame_cycles(void) {
    avr_t *avr = g.h->avr;
    avr_uart_t *u = g.uart;
    const int databits[] = {5, 6, 7, 8, 8, 8, 8, 9};
    const int db = databits[avr_regbit_get(avr, u->ucsz) | (avr_regbit_get(avr, u->ucsz2) << 2)];
    const int bits = 1 + db + 1 + avr_regbit_get(avr, u->usbs);  // start, data, stop(s); no parity
    return bit_cycles() * (uint64_t)bits;
}

// Unread bytes in simavr's RX FIFO (its accessor is defined inside simavr only).
static unsigned rx_fifo_unread(void) {
    const uart_fifo_t *f = &g.uart->input;
    return ((unsigned)f->write + uart_fifo_fifo_size - f->read) & (uart_fifo_fifo_size - 1);
}

static avr_cycle_count_t rx_pump(struct avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)param;
    if (g.rx_head == g.rx_tail) {
        g.pump_running = 0;
        return 0;
    }
    if (!avr_regbit_get(avr, g.uart->rxen)) {
        if (!g.held_counted) {
            g.h->uart_rx_held_before_rxen += (g.rx_head - g.rx_tail) & (RING - 1);
            g.held_counted = 1;
        }
        return when + frame_cycles();
    }
    const uint8_t byte = g.rx[g.rx_tail];
    g.rx_tail = (g.rx_tail + 1) & (RING - 1);
    if (rx_fifo_unread() >= 2) {
        g.h->uart_rx_overruns++;  // the real chip's DOR: this byte is lost
        avr->data[REG_UCSR0A] |= 1u << UCSR0A_DOR0;
    } else {
        avr_raise_irq(g.rx_irq, byte);
        g.h->uart_rx_bytes++;
    }
    return when + frame_cycles();
}

static void append(uint8_t **buf, size_t *len, size_t *cap, const uint8_t *data, size_t n) {
    if (*len + n > *cap) {
        while (*len + n > *cap) *cap = *cap ? *cap * 2 : 65536;
        *buf = realloc(*buf, *cap);
    }
    memcpy(*buf + *len, data, n);
    *len += n;
}

static void on_tx(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    (void)param;
    struct harness *h = g.h;
    append(g.usb_serial ? &g.wire : &g.tx, g.usb_serial ? &g.wire_len : &g.tx_len,
           g.usb_serial ? &g.wire_cap : &g.tx_cap, (const uint8_t *)&(uint8_t){(uint8_t)value}, 1);
    const uint64_t now = h->avr->cycle;
    // Bursts: bytes written to UDR0 no more than one frame time (+5 %) apart, i.e. the
    // firmware kept the line busy. The longest burst's rate is the TX path's throughput.
    if (h->uart_tx_bytes && now - h->uart_tx_last_cycle <= frame_cycles() * 21 / 20) {
        g.burst_bytes++;
    } else {
        g.burst_bytes = 1;
        g.burst_start = now;
    }
    if (g.burst_bytes > h->uart_tx_longest_burst_bytes) {
        h->uart_tx_longest_burst_bytes = g.burst_bytes;
        h->uart_tx_longest_burst_cycles = now - g.burst_start;
    }
    if (!h->uart_tx_bytes) h->uart_tx_first_cycle = now;
    h->uart_tx_last_cycle = now;
    h->uart_tx_bytes++;
}

// Reading UDR0 clears DOR0 (it belongs to the byte read).
static uint8_t on_udr_read(struct avr_t *avr, avr_io_addr_t addr, void *param) {
    (void)param;
    const uint8_t v = g.udr_read(avr, addr, g.udr_param);
    avr->data[REG_UCSR0A] &= (uint8_t)~(1u << UCSR0A_DOR0);
    return v;
}

int uart_bridge_attach(struct harness *h, const char *pty_link, int usb_serial, char *err, size_t errlen) {
    memset(&g, 0, sizeof g);
    g.h = h;
    g.usb_serial = usb_serial;
    for (avr_io_t *io = h->avr->io_port; io; io = io->next)
        if (io->kind && strcmp(io->kind, "uart") == 0 && ((avr_uart_t *)io)->name == '0') g.uart = (avr_uart_t *)io;
    if (!g.uart) {
        snprintf(err, errlen, "this MCU model has no UART0");
        return -1;
    }
    uint32_t flags = 0;
    avr_ioctl(h->avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~(AVR_UART_FLAG_STDIO | AVR_UART_FLAG_POLL_SLEEP);
    avr_ioctl(h->avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    g.rx_irq = avr_io_getirq(h->avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    const avr_io_addr_t udr = AVR_DATA_TO_IO(REG_UDR0);
    g.udr_read = h->avr->io[udr].r.c;
    g.udr_param = h->avr->io[udr].r.param;
    if (g.udr_read) {
        h->avr->io[udr].r.c = on_udr_read;
        h->avr->io[udr].r.param = NULL;
    }
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), on_tx, NULL);

    char name[256];
    if (openpty(&g.master, &g.slave, name, NULL, NULL) < 0) {
        snprintf(err, errlen, "openpty failed: %s", strerror(errno));
        return -1;
    }
    struct termios t;
    tcgetattr(g.slave, &t);
    cfmakeraw(&t);
    tcsetattr(g.slave, TCSANOW, &t);
    fcntl(g.master, F_SETFL, fcntl(g.master, F_GETFL) | O_NONBLOCK);
    unlink(pty_link);
    if (symlink(name, pty_link) < 0) {
        snprintf(err, errlen, "cannot link %s -> %s: %s", pty_link, name, strerror(errno));
        return -1;
    }
    g.ino = -1;
    if (usb_serial) {  // the host's open must be seen: hold no slave of our own
        close(g.slave);
        g.slave = -1;
        g.ino = inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
        if (g.ino < 0 || inotify_add_watch(g.ino, name, IN_OPEN | IN_CLOSE) < 0) {
            snprintf(err, errlen, "cannot watch %s for opens (inotify): %s", name, strerror(errno));
            return -1;
        }
    }
    g.port_open = !usb_serial;
    g.last_rx_wall = wall_s();
    return 0;
}

// usb_serial: the slave's opens and closes since the last look, in order.
static void watch_opens(void) {
    char buf[4096] __attribute__((aligned(__alignof__(struct inotify_event))));
    ssize_t n;
    while ((n = read(g.ino, buf, sizeof buf)) > 0) {
        for (char *p = buf; p < buf + n;) {
            const struct inotify_event *e = (const struct inotify_event *)p;
            if (e->mask & IN_OPEN) {
                if (g.port_open++ == 0) g.port_opened = 1;
            } else if ((e->mask & IN_CLOSE) && g.port_open > 0) {
                g.port_open--;
            }
            p += sizeof *e + e->len;
        }
    }
}

// usb_serial: the host's bytes as UART0 receives them at its own rate.
static size_t carry_to_avr(uint8_t *buf, size_t n, uint8_t *out) {
    if (!avr_regbit_get(g.h->avr, g.uart->rxen)) {
        g.h->uart_rx_lost_rxen_off += n;
        return 0;
    }
    return serial_line_carry(buf, n, serial_line_host_baud(g.master), uart_baud(), out);
}

// usb_serial: the AVR's bytes as the host's end receives them (dropped while the port is closed).
static void carry_to_host(void) {
    if (!g.wire_len) return;
    if (g.port_open) {
        uint8_t *out = malloc(5 * g.wire_len + 1);
        const size_t m = serial_line_carry(g.wire, g.wire_len, uart_baud(), serial_line_host_baud(g.master), out);
        append(&g.tx, &g.tx_len, &g.tx_cap, out, m);
        free(out);
    }
    g.wire_len = 0;
}

size_t uart_bridge_service(struct harness *h, int wait_ms) {
    const uint64_t real = frame_cycles();
    if (g.uart->cycles_per_byte != real) {
        g.uart->cycles_per_byte = real;
        h->uart_cycles_per_byte_fixes++;
    }
    if (g.usb_serial) {
        watch_opens();
        carry_to_host();
        if (!g.port_open) g.tx_len = 0;
    }
    // No opener: the master reports a hang-up at once, so wait on the opens alone.
    struct pollfd pfd[2] = {{g.port_open ? g.master : -1, (short)(POLLIN | (g.tx_len ? POLLOUT : 0)), 0},
                            {g.ino, POLLIN, 0}};
    const int ready = poll(pfd, g.usb_serial ? 2 : 1, wait_ms);
    if (ready <= 0 || !g.port_open) return g.tx_len;
    if (pfd[0].revents & POLLIN) {
        uint8_t buf[4096], carried[5 * sizeof buf + 1];
        const size_t space = (g.rx_tail - g.rx_head - 1) & (RING - 1);
        const size_t room = g.usb_serial ? space / 5 : space;  // a slow receiver may see 5 bytes in one
        const ssize_t n = read(g.master, buf, room < sizeof buf ? room : sizeof buf);
        const size_t m = n <= 0 ? 0 : g.usb_serial ? carry_to_avr(buf, (size_t)n, carried) : (size_t)n;
        const uint8_t *in = g.usb_serial ? carried : buf;
        for (size_t i = 0; i < m; ++i) {
            g.rx[g.rx_head] = in[i];
            g.rx_head = (g.rx_head + 1) & (RING - 1);
        }
        if (n > 0) {
            g.last_rx_cycle = h->avr->cycle;
            g.last_rx_wall = wall_s();
        }
        if (m > 0 && !g.pump_running) {
            g.pump_running = 1;
            avr_cycle_timer_register(h->avr, real, rx_pump, NULL);
        }
    }
    if (g.tx_len && (pfd[0].revents & POLLOUT)) {
        const ssize_t w = write(g.master, g.tx, g.tx_len);
        if (w > 0) {
            memmove(g.tx, g.tx + w, g.tx_len - (size_t)w);
            g.tx_len -= (size_t)w;
        }
    }
    return g.tx_len;
}

int uart_bridge_take_port_opened(void) {
    const int opened = g.port_opened;
    g.port_opened = 0;
    return opened;
}

uint64_t uart_bridge_last_rx_cycle(void) {
    return g.activity_cycle > g.last_rx_cycle ? g.activity_cycle : g.last_rx_cycle;
}

uint64_t uart_bridge_host_rx_cycle(void) { return g.last_rx_cycle; }

void uart_bridge_note_activity(uint64_t cycle) {
    if (cycle > g.activity_cycle) g.activity_cycle = cycle;
}

// The AVR reset: simavr dropped the byte pump's timer; bytes still waiting go on.
void uart_bridge_reset(struct harness *h) {
    g.pump_running = 0;
    g.held_counted = 0;
    if (g.rx_head != g.rx_tail) {
        g.pump_running = 1;
        avr_cycle_timer_register(h->avr, frame_cycles(), rx_pump, NULL);
    }
}
double uart_bridge_last_rx_wall(void) { return g.last_rx_wall; }
void uart_bridge_discard_output(void) { g.tx_len = g.wire_len = 0; }

void uart_bridge_close(void) {
    if (g.master > 0) close(g.master);
    if (g.slave > 0) close(g.slave);
    if (g.ino >= 0) close(g.ino);
    free(g.tx);
    free(g.wire);
    g.tx = g.wire = NULL;
}
