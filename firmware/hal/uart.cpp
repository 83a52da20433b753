#include "uart.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "../config.h"

namespace hal {

namespace {
// 256-byte rings indexed by uint8_t: wrap-around is free and an index is one byte, so
// reading it from the other side is always atomic. One slot stays empty (full = 255).
volatile uint8_t g_rx[256];
volatile uint8_t g_rx_head = 0;  // written by the RX ISR
volatile uint8_t g_rx_tail = 0;  // written by the main loop
volatile uint16_t g_rx_overruns = 0;
volatile uint16_t g_frame_errors = 0;
volatile uint8_t g_tx[256];
volatile uint8_t g_tx_head = 0;  // written by the main loop
volatile uint8_t g_tx_tail = 0;  // written by the UDRE ISR

const uint16_t UBRR_VALUE = static_cast<uint16_t>(F_CPU / (8UL * cfg::BAUD) - 1);
static_assert(F_CPU / (8UL * cfg::BAUD) * (8UL * cfg::BAUD) == F_CPU, "baud rate not exact");
}  // namespace

void uart_init() {
    UBRR0 = UBRR_VALUE;  // 7 at 16 MHz
    UCSR0A = 1 << U2X0;
    UCSR0C = (1 << UCSZ01) | (1 << UCSZ00);  // 8N1
    UCSR0B = (1 << RXEN0) | (1 << TXEN0) | (1 << RXCIE0);
}

int16_t uart_read() {
    const uint8_t tail = g_rx_tail;
    if (tail == g_rx_head) return -1;
    const uint8_t c = g_rx[tail];
    g_rx_tail = static_cast<uint8_t>(tail + 1);
    return c;
}

int16_t uart_peek(uint8_t offset) {
    const uint8_t tail = g_rx_tail;
    const uint8_t waiting = static_cast<uint8_t>(g_rx_head - tail);
    if (offset >= waiting) return -1;
    return g_rx[static_cast<uint8_t>(tail + offset)];
}

void uart_skip(uint8_t n) {
    const uint8_t tail = g_rx_tail;
    const uint8_t waiting = static_cast<uint8_t>(g_rx_head - tail);
    g_rx_tail = static_cast<uint8_t>(tail + (n < waiting ? n : waiting));
}

uint16_t uart_tx_free() { return static_cast<uint8_t>(g_tx_tail - g_tx_head - 1); }

uint16_t uart_write(const uint8_t* data, uint16_t n) {
    uint16_t done = 0;
    uint8_t head = g_tx_head;
    while (done < n && static_cast<uint8_t>(head + 1) != g_tx_tail) {
        g_tx[head] = data[done++];
        ++head;
    }
    g_tx_head = head;
    // UCSR0B is outside the sbi/cbi range and the UDRE ISR clears UDRIE0 itself.
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { UCSR0B |= 1 << UDRIE0; }
    return done;
}

uint16_t uart_rx_overruns() {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { return g_rx_overruns; }
    return 0;
}

uint16_t uart_frame_errors() {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { return g_frame_errors; }
    return 0;
}

}  // namespace hal

ISR(USART0_RX_vect) {
    const uint8_t status = UCSR0A;  // error flags belong to the byte in UDR0: read them first
    const uint8_t c = UDR0;
    if (status & (1 << FE0)) {
        if (hal::g_frame_errors != 0xFFFF) hal::g_frame_errors = hal::g_frame_errors + 1;
        return;
    }
    const bool lost_before = status & (1 << DOR0);
    const uint8_t head = hal::g_rx_head;
    const uint8_t next = static_cast<uint8_t>(head + 1);
    const uint8_t lost = static_cast<uint8_t>((lost_before ? 1 : 0) + (next == hal::g_rx_tail ? 1 : 0));
    if (lost) {
        const uint16_t n = hal::g_rx_overruns;
        hal::g_rx_overruns = n > 0xFFFF - lost ? 0xFFFF : static_cast<uint16_t>(n + lost);
    }
    if (next == hal::g_rx_tail) return;
    hal::g_rx[head] = c;
    hal::g_rx_head = next;
}

ISR(USART0_UDRE_vect) {
    const uint8_t tail = hal::g_tx_tail;
    if (tail == hal::g_tx_head) {
        UCSR0B &= ~(1 << UDRIE0);
        return;
    }
    UDR0 = hal::g_tx[tail];
    hal::g_tx_tail = static_cast<uint8_t>(tail + 1);
}
