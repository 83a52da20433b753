// I2C (TWI) master, 400 kHz.
//
// Contract. Blocking, but every wait is bounded (TWI_TIMEOUT_US per bus event): a stuck
// or absent device returns false and never hangs the main loop. A write sends
// address + bytes + STOP; a read sends address(R), receives n bytes (ACK all but the
// last) + STOP. On any failure the bus is released (STOP, peripheral reset).
#pragma once
#include <stdint.h>

namespace hal {

static const uint16_t TWI_TIMEOUT_US = 1000;

void twi_init();
bool twi_write(uint8_t address7, const uint8_t* data, uint8_t n);
bool twi_read(uint8_t address7, uint8_t* data, uint8_t n);

}  // namespace hal
