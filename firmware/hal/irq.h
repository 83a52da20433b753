// Interrupt masking for data shared with interrupt handlers.
//
// Contract. An InterruptLock masks interrupts for its lifetime and restores the
// previous state (not blindly re-enables) when it ends, so locks nest. On the AVR it is
// ATOMIC_BLOCK(ATOMIC_RESTORESTATE) in RAII form (save SREG, cli; restore SREG). In the
// native tests (tests/fake_hal.cpp) it defers simulated interrupts until the outermost
// lock ends, exactly like the AVR's latched interrupt flags. Hold it for a few
// instructions only: every cycle held adds to the latency of the step and UART ISRs.
#pragma once
#include <stdint.h>

namespace hal {

class InterruptLock {
public:
    InterruptLock();
    ~InterruptLock();

private:
    InterruptLock(const InterruptLock&);
    InterruptLock& operator=(const InterruptLock&);
    uint8_t saved_;
};

// Read or write a multi-byte variable that an ISR also writes. On an 8-bit MCU a
// 32-bit load is four byte loads; an interrupt between them tears the value (the
// prototype rig lost 255 of 1000 steps that way). Always go through these.
template <typename T>
inline T atomic_load(const volatile T& v) {
    InterruptLock lock;
    return v;
}

template <typename T>
inline void atomic_store(volatile T& v, T value) {
    InterruptLock lock;
    v = value;
}

}  // namespace hal
