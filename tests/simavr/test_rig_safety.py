"""The firmware on the emulated rig where a real Mega is unforgiving: resets (the DTR
pulse, the stk500v2 bootloader, a hung main loop), the twist zero across them, the heater
power actually applied, a faulty I2C bus. Each test fails on the firmware before these
were fixed (noted per test)."""

from __future__ import annotations

import math
import subprocess
import time

from tests import conformance_scenarios as sc
from tests.simavr.conftest import SIMAVR_BENCH, simavr_port
from tsa_bench.protocol import encode, msg
from tsa_bench.bench.simavr_section import SimavrSettings
from tsa_bench.simavr import SimavrBench

E, S, STATE = msg.EventKind, msg.Status, msg.DeviceState
SETTLE_S, FIRST_REPLY_S = 0.08, 2.0


def exchange(port) -> sc.Exchange:
    return sc.Exchange(port, settle_s=SETTLE_S, first_reply_s=FIRST_REPLY_S)



def wait_boot(ex: sc.Exchange, since: int, timeout_s: float = 30.0, heartbeat: bool = False) -> msg.Boot:
    """The first BOOT among the messages from index ``since`` on; with ``heartbeat`` a
    HEARTBEAT every 0.2 s of wall time meanwhile (answered or not: the device may hang)."""
    start, deadline, beat = since, time.monotonic() + timeout_s, time.monotonic()
    while time.monotonic() < deadline:
        boots = [m for m in ex.received[start:] if isinstance(m, msg.Boot)]
        if boots:
            return boots[-1]
        if heartbeat and time.monotonic() - beat > 0.2:
            ex.seq += 1
            ex.port.write(encode(msg.Heartbeat(), ex.seq))
            beat = time.monotonic()
        ex._read_some()
    raise AssertionError("no BOOT after the reset")


def test_position_kept_across_a_dtr_reset_and_unknown_after_one_mid_move(firmware_dir):
    """A pull-down on /ENABLE keeps the A4988 energized through the reset and the ~1 s
    bootloader: the position survives in .noinit, when the host armed the reset
    (ARM_RESET before it reopens the port), and the host is told so. A reset while the
    motor turns leaves it unknown, and moves are refused until SET_POSITION.
    (Before: every reset set the position to a silent 0.)"""
    with simavr_port(firmware_dir) as (port, bench):
        assert bench.boot_message.reason == msg.BootReason.POWER_ON   # the bootloader cleared PORF
        ex = exchange(port)
        sc.handshake(ex)
        start = len(ex.received)
        ex.send(msg.MoveTo(1, 6400, 16_000, 320_000))
        ex.wait_for(lambda m: isinstance(m, msg.Event) and m.kind == E.QUEUE_EMPTY, 30, since=start)
        assert ("ACK", 0x07, "OK", 16) in ex.send(msg.ArmReset())
        since = len(ex.received)
        bench.reset()                                              # the host reopens the port
        boot = wait_boot(ex, since)
        assert boot.reason == msg.BootReason.EXTERNAL_RESET
        ex.send(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH))
        qs = ex.send_for(msg.Heartbeat(), msg.QueueStatus)
        assert qs.state == 0 and qs.step_position == 6400          # kept, and said so
        start = len(ex.received)
        ex.send(msg.SetSampling(1, 20_000))
        ex.send(msg.MoveTo(2, 64_000, 16_000, 320_000))
        ex.wait_for(lambda m: isinstance(m, msg.Sample) and m.motor_moving and m.step_position > 20_000, 30,
                    since=start)
        since = len(ex.received)
        bench.reset()                                              # reset mid-move
        assert wait_boot(ex, since).reason == msg.BootReason.EXTERNAL_RESET
        ex.send(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH))
        qs = ex.send_for(msg.Heartbeat(), msg.QueueStatus)
        assert qs.state & STATE.POSITION_UNKNOWN
        refused = ex.send(msg.MoveTo(3, 0, 16_000, 320_000))
        assert [r[2] for r in refused if r[0] == "ACK"] == ["BAD_STATE"]
    s = bench.summary
    assert [r["cause"] for r in s["reset_log"]] == ["power_on", "external", "external"]
    assert s["steps"]["backdriven"] == 0                           # the driver never let go
    assert s["clock_zero_s"] >= 1.0                                # the bootloader ran first
    assert all(v == 0 for v in s["violations"].values()), s["violations"]


def test_a_pulled_up_enable_releases_the_motor_and_the_position_is_unknown(firmware_dir):
    """With a pull-up on /ENABLE the motor is released while the AVR resets and the
    loaded strings turn it back: the firmware reads /ENABLE high at start and reports the
    position unknown instead of the stale count."""
    with simavr_port(firmware_dir, enable_pull="up") as (port, bench):
        ex = exchange(port)
        sc.handshake(ex)
        start = len(ex.received)
        ex.send(msg.MoveTo(1, 6400, 16_000, 320_000))
        ex.wait_for(lambda m: isinstance(m, msg.Event) and m.kind == E.QUEUE_EMPTY, 30, since=start)
        since = len(ex.received)
        bench.reset()
        wait_boot(ex, since)
        ex.send(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH))
        qs = ex.send_for(msg.Heartbeat(), msg.QueueStatus)
        assert qs.state & STATE.POSITION_UNKNOWN
    assert bench.summary["steps"]["backdriven"] > 0


def test_a_hung_main_loop_is_made_safe_by_the_watchdog_interrupt_without_a_reset_loop(firmware_dir):
    """The main loop hangs (a `rjmp .` at 8 s) with the heater on and the motor turning,
    on a board with the 2011 bootloader: the watchdog interrupt turns the heater off and
    stops STEP within its period, restarts the firmware without a hardware reset (that
    bootloader would reset forever), and the next BOOT says watchdog_reset with the
    position unknown (it was moving). (Before: a watchdog system reset: an endless loop
    on this bootloader, and reason external_reset on the stock one.)"""
    # 8 s of harness time: after the commands below even when the AVR runs its full lead
    # (1 s) ahead of each of them
    with simavr_port(firmware_dir, bootloader="2011", hang_at_s=8.0) as (port, bench):
        ex = exchange(port)
        sc.handshake(ex)
        ex.send(msg.SetSampling(1, 20_000))
        ex.send(msg.SetHeater(2, 5000))
        ex.send(msg.MoveTo(3, 300_000, 1_000, 10_000))             # still turning at 8 s
        since = len(ex.received)
        # heartbeats throughout: the host watchdog must not be what stops the motor
        boot = wait_boot(ex, since, heartbeat=True)
        assert any(isinstance(m, msg.Sample) and m.motor_moving and m.t_us > 1_000_000 for m in ex.received[since:])
        assert boot.reason == msg.BootReason.WATCHDOG_RESET
        ex.send(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH))
        qs = ex.send_for(msg.Heartbeat(), msg.QueueStatus)
        assert qs.state & STATE.POSITION_UNKNOWN
    s = bench.summary
    hang = [r["t_s"] for r in s["reset_log"] if r["cause"] == "hang_injected"]
    assert len(hang) == 1
    assert s["resets"] == 0 and s["app_starts"] == 2               # restarted, never reset
    assert 0 < s["heater"]["last_off_s"] - hang[0] < 0.15          # the WDT period (~128 ms)
    assert not s["drive"]["sense_on"]


def test_a_hang_with_interrupts_masked_ends_in_a_watchdog_system_reset(firmware_dir):
    """A hang with interrupts masked (inside an ISR or an atomic block) cannot run the
    watchdog interrupt: the chip resets at the next time-out (the datasheet's
    interrupt-and-reset mode; simavr 1.6 alone never would). The reset turns the heater
    off and the firmware boots again. The stock bootloader clears MCUSR and jumps
    straight to the application after a watchdog reset, and the firmware's watchdog ISR
    never ran: the BOOT can only say external_reset (firmware/README.md)."""
    with simavr_port(firmware_dir, hang_at_s=8.0, hang_masked=True) as (port, bench):
        ex = exchange(port)
        sc.handshake(ex)
        ex.send(msg.SetSampling(1, 20_000))
        ex.send(msg.SetHeater(2, 5000))
        since = len(ex.received)
        boot = wait_boot(ex, since, heartbeat=True)
        assert boot.reason == msg.BootReason.EXTERNAL_RESET
    s = bench.summary
    hang = [r["t_s"] for r in s["reset_log"] if r["cause"] == "hang_injected_masked"]
    resets = [r["t_s"] for r in s["reset_log"] if r["cause"] == "watchdog"]
    assert len(hang) == 1 and len(resets) == 1 and s["resets"] == 1
    assert 0.2 < resets[0] - hang[0] < 0.3                         # two periods of ~128 ms
    assert 0 < s["heater"]["last_off_s"] - hang[0] < 0.3            # off by the reset at the latest


def test_the_heater_applies_the_voltage_it_reports(firmware_dir):
    """Each request is applied within 2 % from 1 V up, and SAMPLE reports the voltage
    applied: the harness integrates the gate's duty on Timer2's real (OCR2A + 1)/256
    scale. (Before: 1 V left the heater off, 2 V applied 2.12 V, and SAMPLE reported the
    request.)"""
    requests = [1000, 2000, 5000, 12000]
    with simavr_port(firmware_dir) as (port, bench):
        ex = exchange(port)
        sc.handshake(ex)
        ex.send(msg.SetSampling(1, 20_000))
        reported = []
        for i, mV in enumerate(requests):
            ex.send(msg.SetHeater(2 + 2 * i, mV))
            ex.wait_device_s(0.3)
            reported.append(ex.samples[-1].heater_mV)
            ex.send(msg.SetHeater(3 + 2 * i, 0))
            ex.wait_device_s(0.1)
    supply_V = SIMAVR_BENCH.simavr["heater_supply_V"]
    periods = bench.summary["heater"]["periods"]
    assert len(periods) == len(requests)
    for mV, got_mV, p in zip(requests, reported, periods):
        applied_V = supply_V * math.sqrt(p["mean_duty"])
        assert abs(applied_V - mV / 1000) / (mV / 1000) < 0.02, (mV, applied_V)
        assert abs(applied_V - got_mV / 1000) / (got_mV / 1000) < 0.005, (got_mV, applied_V)


def test_i2c_faults_nack_stretch_and_a_stuck_bus_recovered(firmware_dir):
    """The position ADC NACKs for 0.2 s, then stretches every byte by 40 us, then holds
    SDA low (a slave stuck mid-byte): NACKed samples say position_invalid, stretched ones
    are fine, and the stuck bus is freed with SCL clocks and a STOP, counted as an EVENT
    i2c_recovered and in QUEUE_STATUS; positions come back. (Before: no recovery, every
    later sample position_invalid.)"""
    # harness times late enough that sampling runs by then however far the AVR ran ahead
    # (its lead, 1 s) while the host sent the commands
    faults = ("nack:5.0:5.2", "stretch:5.4:5.7:40", "stuck:5.9:8")
    with simavr_port(firmware_dir, twi_faults=faults) as (port, bench):
        ex = exchange(port)
        sc.handshake(ex)
        start = len(ex.received)
        ex.send(msg.SetSampling(1, 20_000))
        ex.wait_for(lambda m: isinstance(m, msg.Event) and m.kind == E.I2C_RECOVERED, 60, since=start)
        ex.wait_device_s(0.3)
        qs = ex.send_for(msg.Heartbeat(), msg.QueueStatus)
    clock0 = bench.summary["clock_zero_s"]
    invalid = msg.AdcFlags.POSITION_INVALID

    def in_window(s, t0, t1):
        return t0 + 0.01 < s.t_us * 1e-6 + clock0 < t1 - 0.01

    nacked = [s for s in ex.samples if in_window(s, 5.0, 5.2)]
    stretched = [s for s in ex.samples if in_window(s, 5.4, 5.7)]
    assert nacked and all(s.adc_flags & invalid for s in nacked)
    assert stretched and not any(s.adc_flags & invalid for s in stretched)
    recovered = [e for e in ex.events if e.kind == E.I2C_RECOVERED]
    assert len(recovered) == 1 and recovered[0].code == 1 and qs.i2c_recoveries == 1
    assert not ex.samples[-1].adc_flags & invalid                  # positions are back
    twi = bench.summary["twi"]
    assert twi["stuck_events"] == 1 and twi["releases"] == 1 and twi["manual_scl_clocks"] >= 5
    assert twi["naks_injected"] > 0 and twi["stretched_bytes"] > 0


def test_twi_byte_time_follows_twbr(firmware_dir, tmp_path):
    """simavr 1.6 takes 9 us for a byte whatever the bit rate; the harness times it from
    TWBR: a program raises STEP when it starts an address byte and lowers it at TWINT,
    so STEP's high time is the byte on the bus: 9 x (16 + 2 TWBR) cycles."""
    widths = {}
    for twbr in (12, 72):
        src = tmp_path / f"twi{twbr}.c"
        src.write_text(f"""#include <avr/io.h>
int main(void) {{
  DDRA = 0x05; PORTA = 0x00;
  TWBR = {twbr}; TWSR = 0; TWCR = (1 << TWINT) | (1 << TWSTA) | (1 << TWEN);
  while (!(TWCR & (1 << TWINT))) {{}}
  TWDR = 0x48 << 1; PORTA |= 1; TWCR = (1 << TWINT) | (1 << TWEN);
  while (!(TWCR & (1 << TWINT))) {{}}
  PORTA &= ~1;
  for (;;) {{}} }}
""")
        build = tmp_path / f"fw{twbr}" / "build"
        build.mkdir(parents=True)
        subprocess.run(["avr-gcc", "-mmcu=atmega2560", "-O1", str(src), "-o", str(build / "tsa_bench.elf")],
                       check=True)
        (build / "tsa_simavr").symlink_to(firmware_dir / "build" / "tsa_simavr")
        with SimavrBench(SIMAVR_BENCH, SimavrSettings(firmware_dir=build.parent, build=False,
                                                      bootloader="none")) as bench:
            bench.start()
            time.sleep(0.3)
        widths[twbr] = bench.summary["steps"]["min_high_cycles"]
    for twbr, cycles in widths.items():
        assert abs(cycles - 9 * (16 + 2 * twbr)) <= 12, widths     # + a few instructions


def test_an_unarmed_reset_and_a_hidden_brown_out_leave_the_position_unknown(firmware_dir):
    """A brown-out: SRAM keeps the record, the stock bootloader clears BORF (the record
    alone would read external_reset), and the A4988's translator restarts at Home, moving
    the rotor. The host never armed that reset: the position is unknown. So is it after a
    DTR reset the host did not arm (a second tool opening the port). (Before: the record
    said external_reset, /ENABLE read low, and the stale count was kept.)"""
    with simavr_port(firmware_dir) as (port, bench):
        ex = exchange(port)
        sc.handshake(ex)
        start = len(ex.received)
        ex.send(msg.MoveTo(1, 6_420, 16_000, 320_000))             # 20 microsteps past a Home position
        ex.wait_for(lambda m: isinstance(m, msg.Event) and m.kind == E.QUEUE_EMPTY, 30, since=start)
        since = len(ex.received)
        bench.brown_out()
        assert wait_boot(ex, since).reason == msg.BootReason.EXTERNAL_RESET   # BORF hidden by the bootloader
        ex.send(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH))
        qs = ex.send_for(msg.Heartbeat(), msg.QueueStatus)
        assert qs.state & STATE.POSITION_UNKNOWN
        ex.send(msg.SetPosition(0))
        since = len(ex.received)
        bench.reset()                                              # a DTR reset nobody armed
        wait_boot(ex, since)
        ex.send(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH))
        qs = ex.send_for(msg.Heartbeat(), msg.QueueStatus)
        assert qs.state & STATE.POSITION_UNKNOWN
    s = bench.summary
    assert [r["cause"] for r in s["reset_log"]] == ["power_on", "brown_out", "external"]
    assert s["steps"]["home_shift"] == -20                         # the count would have been 20 steps off
