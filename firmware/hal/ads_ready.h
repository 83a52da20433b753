// ADS1115 continuous conversions stamped at their ALERT/RDY edge (hal/pins.h: PE4, INT4).
//
// Contract (AVR only). In continuous mode with the conversion-ready function on, the
// ADS1115 pulls ALERT/RDY low for ~8 us at the end of every conversion (data sheet
// SBAS444, 9.3.8), and the next conversion starts then. ads_stream_start(every) arms
// INT4 on the falling edge. Its ISR takes the time (Timer3 with its overflow base,
// micros32_locked) and the step position (step_position16_locked) at the edge: the edge
// that ends one conversion is the start of the next, so each sample is stamped with
// its conversion's start, the previous edge, whatever the chip's real rate. Every
// `every`-th edge the ISR queues a sample {previous edge's time and position} in a ring
// of ADS_STREAM_SLOTS and starts the interrupt-driven 2-byte read of the conversion just
// finished (hal/twi.h; the pointer register was left on the conversion register); the
// TWI interrupt fills in the counts. The first edge after the start is only a
// reference. ads_stream_take() gives the oldest sample whose read is over (ok or
// failed) and how many were lost before it (the ring was full: the main loop did not
// come for ADS_STREAM_SLOTS samples). ads_stream_edges() gives the edges since the
// start and the time of the last (for the conversion period and the liveness check). ads_stream_stop() disarms INT4 and forgets queued samples. Times are
// the low 32 bits of the microsecond clock.
#pragma once
#include <stdint.h>

namespace hal {

static const uint8_t ADS_STREAM_SLOTS = 8;  // a power of two

struct AdsSample {
    uint32_t t_us;           // conversion start (the previous ALERT/RDY edge)
    uint16_t step_position16;  // at t_us, low 16 bits (hal::step_position_near)
    uint8_t bytes[2];        // the conversion register, MSB first
    uint8_t status;          // hal::TWI_ASYNC_OK or TWI_ASYNC_FAILED (never pending here)
};

void ads_stream_start(uint8_t address7, uint8_t every);
void ads_stream_stop();
bool ads_stream_take(AdsSample& s, uint8_t& lost);
void ads_stream_edges(uint16_t& edges, uint32_t& last_us);  // edges wrap at 65536

}  // namespace hal
