// UART0, interrupt driven (AVR only).
//
// Contract. 250000 baud with U2X (UBRR0 = 7 at 16 MHz, 0 % error), 8N1. The RX ISR only
// moves the byte into a 256-byte ring (a full ring drops the byte and counts it); the
// UDRE ISR drains a 256-byte TX ring. Single producer / single consumer per ring with
// one-byte indices, so the main loop and the ISRs never tear an index.
#pragma once
#include <stdint.h>

namespace hal {

void uart_init();
int16_t uart_read();               // next byte or -1
uint16_t uart_tx_free();
uint16_t uart_write(const uint8_t* data, uint16_t n);
uint16_t uart_rx_overruns();       // bytes dropped because the RX ring was full

}  // namespace hal
