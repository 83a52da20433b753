#include "irq.h"

#include <avr/interrupt.h>
#include <avr/io.h>

namespace hal {

// ATOMIC_BLOCK(ATOMIC_RESTORESTATE) split into constructor/destructor.
InterruptLock::InterruptLock() : saved_(SREG) {
    cli();
    __asm__ __volatile__("" ::: "memory");
}

InterruptLock::~InterruptLock() {
    __asm__ __volatile__("" ::: "memory");
    SREG = saved_;
}

}  // namespace hal
