#!/usr/bin/env python3
"""Worst-case cycle counts of the firmware's time-critical ISRs, from the disassembly.

Usage: scripts/isr_cycles.py build/tsa_bench.elf [--mhz 16]

For the step-timer ISR (TIMER1_COMPA, vector 17 on the ATmega2560), the UART0 RX ISR
(USART0_RX, vector 25), the heater dither (TIMER2_COMPA, 13), the ADS1115's ALERT/RDY
edge (INT4, 5) and the TWI read it starts (TWI, 39) it disassembles the ELF with
avr-objdump -d, builds the control-flow graph from the handler's entry and finds the
longest path to `reti` (calls are followed and charged with the callee's own longest
path). The vector numbers are checked against avr-libc's header and against the vector
table in the ELF. It also checks, on the shortest path, that the step ISR keeps STEP
high >= 1 us, and fails when the step ISR's worst case exceeds --step-budget cycles
(150: about Klipper's AVR step path; 15 % of the CPU at 16,000 steps/s).

Cycle costs are the AVR instruction set manual's for the ATmega2560 (AVRe+, 3-byte PC:
CALL 5, RCALL/ICALL/EICALL 4, RET/RETI 5, JMP 3; a taken branch 2; a skip over a
two-word instruction 3). Where the manual gives a range the larger value is used. The
interrupt response (5 cycles with a 3-byte PC) and the JMP in the vector table (3) are
added; the instruction that is executing when the interrupt arrives (up to 5 more
cycles) and other ISRs that run first are latency, reported separately, not included.
Any loop or indirect jump in a handler makes the bound unknown: the script fails.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
from functools import lru_cache
from pathlib import Path

INTERRUPT_RESPONSE = 5  # 3-byte PC devices
VECTOR_JMP = 3
MAX_INSTRUCTION_IN_PROGRESS = 5

ISRS = [  # (vector, avr-libc name, description)
    (17, "TIMER1_COMPA_vect", "step timer"),
    (25, "USART0_RX_vect", "UART0 RX"),
    (13, "TIMER2_COMPA_vect", "heater PWM dither"),
    (5, "INT4_vect", "ADS1115 ALERT/RDY edge: stamp, sample, start its read"),
    (39, "TWI_vect", "interrupt-driven ADS1115 read"),
]
LIBC_HEADER = Path("/usr/lib/avr/include/avr/iomxx0_1.h")

FIXED = {
    # 1 cycle
    **{m: 1 for m in "add adc sub subi sbc sbci and andi or ori eor com neg sbr cbr inc dec tst clr ser "
                     "cp cpc cpi mov movw ldi in out lsl lsr rol ror asr swap bset bclr bst bld sec clc "
                     "sen cln sez clz sei cli ses cls sev clv set clt seh clh nop sleep wdr break".split()},
    # 2 cycles
    **{m: 2 for m in "adiw sbiw mul muls mulsu fmul fmuls fmulsu rjmp ijmp eijmp lds sts ldd std "
                     "push pop sbi cbi st".split()},
    "ld": 2,  # pre-decrement forms cost 3, handled below
    "jmp": 3, "lpm": 3, "elpm": 3,
    "rcall": 4, "icall": 4, "eicall": 4, "call": 5, "ret": 5, "reti": 5,
}
BRANCHES = {"breq", "brne", "brcs", "brcc", "brsh", "brlo", "brmi", "brpl", "brge", "brlt", "brhs",
            "brhc", "brts", "brtc", "brvs", "brvc", "brie", "brid", "brbs", "brbc"}
SKIPS = {"cpse", "sbrc", "sbrs", "sbic", "sbis"}

LINE = re.compile(r"^\s*([0-9a-f]+):\s+((?:[0-9a-f]{2} )+)\s*\t(\S+)\s*([^;]*)(?:;\s*0x([0-9a-f]+))?")
SYMBOL = re.compile(r"^([0-9a-f]+) <([^>]+)>:")


class Unbounded(Exception):
    pass


def disassemble(elf: Path):
    out = subprocess.run(["avr-objdump", "-d", str(elf)], check=True, capture_output=True, text=True).stdout
    insns, symbols = {}, {}
    for line in out.splitlines():
        m = SYMBOL.match(line)
        if m:
            symbols[m.group(2)] = int(m.group(1), 16)
            continue
        m = LINE.match(line)
        if m:
            addr = int(m.group(1), 16)
            size = len(m.group(2).split())
            target = int(m.group(5), 16) if m.group(5) else None
            insns[addr] = (size, m.group(3), m.group(4).strip(), target)
    return insns, symbols


def cost(mnemonic: str, operands: str) -> int:
    if mnemonic in ("ld", "st") and "-" in operands:
        return 3 if mnemonic == "ld" else 2
    if mnemonic in FIXED:
        return FIXED[mnemonic]
    raise Unbounded(f"unknown instruction {mnemonic} {operands}")


def successors(insns, addr):
    """(next address or None for a return, cycles, callee or None) for each way out."""
    size, mn, ops, target = insns[addr]
    nxt = addr + size
    if mn in ("ret", "reti"):
        return [(None, 5, None)]
    if mn in ("ijmp", "eijmp", "icall", "eicall"):
        raise Unbounded(f"indirect {mn} at {addr:#x}")
    if mn in ("rjmp", "jmp"):
        return [(target, cost(mn, ops), None)]
    if mn in ("call", "rcall"):
        return [(nxt, cost(mn, ops), target)]
    if mn in BRANCHES:
        return [(nxt, 1, None), (target, 2, None)]
    if mn in SKIPS:
        skipped = insns[nxt][0]  # bytes: 2 = one-word instruction, 4 = two-word
        return [(nxt, 1, None), (nxt + skipped, 2 if skipped == 2 else 3, None)]
    return [(nxt, cost(mn, ops), None)]


def make_longest(insns):
    visiting = set()

    @lru_cache(maxsize=None)
    def longest(addr):
        """Longest (cycles, instructions) from addr to the ret/reti that ends the routine."""
        if addr not in insns:
            raise Unbounded(f"jump outside the disassembly to {addr:#x}")
        if addr in visiting:
            raise Unbounded(f"loop through {addr:#x}")
        visiting.add(addr)
        best = None
        for nxt, cyc, callee in successors(insns, addr):
            total, count = cyc, 1
            if callee is not None:
                c, n = longest(callee)
                total, count = total + c, count + n
            if nxt is not None:
                c, n = longest(nxt)
                total, count = total + c, count + n
            if best is None or total > best[0]:
                best = (total, count)
        visiting.discard(addr)
        return best

    return longest


def shortest_between(insns, start, stop):
    """Fewest cycles executed after `start` up to and including `stop` (DAG, no calls)."""
    @lru_cache(maxsize=None)
    def go(addr):
        if addr == stop:
            return cost(insns[addr][1], insns[addr][2])
        best = None
        for nxt, cyc, callee in successors(insns, addr):
            if nxt is None:
                continue
            if callee is not None:
                raise Unbounded("call between STEP edges")
            rest = go(nxt)
            if rest is not None and (best is None or cyc + rest < best):
                best = cyc + rest
        return best

    first = None
    for nxt, cyc, _ in successors(insns, start):
        rest = go(nxt) if nxt is not None else None
        if rest is not None and (first is None or rest < first):
            first = rest
    return first


def check_vector_numbers(insns, symbols):
    problems = []
    header = LIBC_HEADER.read_text() if LIBC_HEADER.exists() else ""
    for num, name, _ in ISRS:
        if header and not re.search(rf"#define\s+{name}\s+_VECTOR\({num}\)", header):
            problems.append(f"{name} is not _VECTOR({num}) in {LIBC_HEADER}")
        slot = insns.get(4 * num)  # table entries are 4-byte JMPs
        if not slot or slot[1] != "jmp" or slot[3] != symbols.get(f"__vector_{num}"):
            problems.append(f"vector table slot {num} does not jump to __vector_{num}")
    return problems


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("elf", type=Path)
    ap.add_argument("--mhz", type=float, default=16.0)
    ap.add_argument("--step-port", default="0x02", help="I/O address of the STEP port (PORTA)")
    ap.add_argument("--step-bit", default="0")
    ap.add_argument("--step-budget", type=int, default=150, help="worst-case cycles allowed for the step ISR")
    args = ap.parse_args()

    insns, symbols = disassemble(args.elf)
    problems = check_vector_numbers(insns, symbols)
    for p in problems:
        print(f"ERROR: {p}")
    if not problems:
        print("vectors: " + ", ".join(f"{name} = __vector_{num}" for num, name, _ in ISRS)
              + " (avr-libc header and the ELF's vector table agree)")
    longest = make_longest(insns)
    ok = not problems
    for num, name, what in ISRS:
        sym = f"__vector_{num}"
        if sym not in symbols:
            print(f"ERROR: {sym} ({name}) not found in {args.elf}")
            ok = False
            continue
        try:
            body, count = longest(symbols[sym])
        except Unbounded as e:
            print(f"ERROR: {sym} ({name}): cannot bound: {e}")
            ok = False
            continue
        total = body + INTERRUPT_RESPONSE + VECTOR_JMP
        if num == 17 and total > args.step_budget:
            print(f"ERROR: {sym} ({name}) worst case {total} cycles exceeds the budget of {args.step_budget}")
            ok = False
        print(f"{sym} ({name}, {what}): worst case {total} cycles = {total / args.mhz:.2f} us at "
              f"{args.mhz:g} MHz  [handler {body} cycles over {count} instructions + response "
              f"{INTERRUPT_RESPONSE} + vector jmp {VECTOR_JMP}; plus up to "
              f"{MAX_INSTRUCTION_IN_PROGRESS} cycles latency for the instruction in progress]")

    # STEP high time inside the step ISR.
    sbi = [a for a, (_, mn, ops, _) in insns.items()
           if mn == "sbi" and ops.replace(" ", "") == f"{args.step_port},{args.step_bit}"]
    cbi = [a for a, (_, mn, ops, _) in insns.items()
           if mn == "cbi" and ops.replace(" ", "") == f"{args.step_port},{args.step_bit}"]
    entry = symbols.get("__vector_17", -1)
    end = min((a for a in symbols.values() if a > entry), default=1 << 30)
    sbi = [a for a in sbi if entry <= a < end]
    cbi = [a for a in cbi if entry <= a < end]
    if len(sbi) == 1 and len(cbi) == 1:
        high = shortest_between(insns, sbi[0], cbi[0])
        need = int(args.mhz)  # 1 us
        verdict = "OK" if high is not None and high >= need else "TOO SHORT"
        print(f"STEP high in __vector_17: at least {high} cycles = {high / args.mhz:.2f} us "
              f"(A4988 needs >= 1 us = {need} cycles): {verdict}")
        ok = ok and verdict == "OK"
    else:
        print(f"ERROR: expected one sbi/cbi of the STEP pin in __vector_17, found {len(sbi)}/{len(cbi)}")
        ok = False
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
