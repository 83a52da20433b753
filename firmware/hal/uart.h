// UART0, interrupt driven (AVR only).
//
// Contract. 250000 baud with U2X (UBRR0 = 7 at 16 MHz, 0 % error), 8N1. The RX ISR only
// moves the byte into a 256-byte ring (a full ring drops the byte and counts it), after
// reading UCSR0A: a byte with a framing error (FE0) is dropped and counted, a receiver
// overrun (DOR0: a byte was lost before this one) is counted; the UDRE ISR drains a
// 256-byte TX ring. Single producer / single consumer per ring with
// one-byte indices, so the main loop and the ISRs never tear an index.
#pragma once
#include <stdint.h>

namespace hal {

void uart_init();
int16_t uart_read();               // next byte or -1
int16_t uart_peek(uint8_t offset); // the byte `offset` after the next one, left in place, or -1
void uart_skip(uint8_t n);         // drop the next n bytes
uint16_t uart_tx_free();
uint16_t uart_write(const uint8_t* data, uint16_t n);
// Counters since boot, saturating at 65535: bytes lost (receiver overrun or RX ring
// full) and bytes received with a framing error.
uint16_t uart_rx_overruns();
uint16_t uart_frame_errors();

}  // namespace hal
