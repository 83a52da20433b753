// A stand-in for the Arduino Mega's stk500v2 bootloader, run by the harness at every
// reset (firmware/sim/README.md). Written from the bootloader's documented behaviour
// (no code of it): what the application can notice is reproduced, nothing else.
//
//   * It runs first after every reset (BOOTRST: the reset vector is 0x3E000), with
//     the application's pins as the reset left them: inputs, floating (only the LED
//     pin, PB7, is driven), for 0.83 s while it listens for a programmer.
//   * It uses SRAM: a few globals at the bottom and its stack, with a 285-byte message
//     buffer, at the top. Both regions are overwritten here with a pattern.
//   * STOCK (the bootloader Arduino ships since 2012, and Debian's arduino-core-avr):
//     it clears MCUSR and turns the watchdog off. After a watchdog reset it means to
//     start the application at once, through a function pointer (EICALL), but its C
//     start-up has set EIND to 1 for the boot section: the call lands at 0x20000, in
//     erased flash below an application of less than 128 KB, and the chip runs on into
//     the bootloader, which now finds MCUSR clear and waits its 0.83 s as after any
//     reset. So here: no early start (checked against the real bootloader's hex,
//     tests/simavr/test_flash_bootloader.py).
//   * OLD_2011 (boards programmed with the 2011 release): it leaves MCUSR and the
//     watchdog alone. After a watchdog reset the WDT is still armed at 16 ms, the
//     wait never ends and the board resets forever.
// Built with avr-gcc -nostartfiles, linked at 0x3E000 (firmware/Makefile, `harness`).
#include <avr/io.h>
#include <stdint.h>

// 0.83 s at 16 MHz: the real bootloader's wait from reset to the application's start
// (20,000 polls of the UART, measured on its hex in simavr; a test keeps them within 2 %).
#define BOOT_WAIT_CYCLES 13320000UL
#define LOW_RAM_BYTES 64
#define HIGH_RAM_BYTES 600

// Named __vectors: simavr takes the load address of a bootloader ELF from that symbol.
__attribute__((naked, noreturn, used, section(".vectors"))) void __vectors(void) {
    __asm__ __volatile__("clr r1");
#ifdef STOCK
    MCUSR = 0;
    WDTCSR = (1 << WDCE) | (1 << WDE);
    WDTCSR = 0;
#endif
    for (uint16_t a = RAMSTART; a < RAMSTART + LOW_RAM_BYTES; ++a) *(volatile uint8_t *)a = 0xA5;
    for (uint16_t a = RAMEND - HIGH_RAM_BYTES + 1; a != RAMEND + 1; ++a) *(volatile uint8_t *)a = 0x5A;
    DDRB = 1 << PB7;  // the "L" LED blinks while it waits
    PORTB = 1 << PB7;
    __builtin_avr_delay_cycles(BOOT_WAIT_CYCLES);
    PORTB = 0;
    DDRB = 0;
    __asm__ __volatile__("jmp 0");
    for (;;) {
    }
}
