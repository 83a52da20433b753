"""The simavr harness itself: wiring agrees with the firmware's pin map, steps and
timing are watched, and it stops cleanly, reports crashes and a lost plant."""

from __future__ import annotations

import json
import re
import subprocess
import time
from pathlib import Path

import pytest
import serial

from tests import conformance_scenarios as sc
from tests.simavr.conftest import SIMAVR_BENCH, simavr_port
from tsa_bench.protocol import msg
from tsa_bench.bench.simavr_section import SimavrSettings
from tsa_bench.simavr import SimavrBench


def test_rig_map_matches_the_firmware_pin_map(repo_root):
    pins = dict((name, (port, int(bit))) for name, port, bit in re.findall(
        r"X\((PIN_\w+), ([A-L]), (\d)\)", (repo_root / "firmware/hal/pins.h").read_text()))
    rig = (repo_root / "firmware/sim/rig_map.h").read_text()
    defs = dict(re.findall(r"#define (RIG_\w+) (\S+)", rig))
    pairs = {"STEP": "PIN_MOTOR_STEP", "DIR": "PIN_MOTOR_DIR", "EN": "PIN_MOTOR_EN", "RES_CS": "PIN_RES_CS",
             "RES_SCLK": "PIN_RES_SCLK", "RES_SDO": "PIN_RES_SDO", "ISRC_EN": "PIN_ISRC_EN",
             "HEATER": "PIN_HEATER"}
    for rig_name, pin in pairs.items():
        assert (defs[f"RIG_{rig_name}_PORT"].strip("'"), int(defs[f"RIG_{rig_name}_BIT"])) == pins[pin], rig_name
    pins_h = (repo_root / "firmware/hal/pins.h").read_text()
    rdy = re.search(r"#define PINS_ADS_RDY_PIN PIN([A-L])\s+#define PINS_ADS_RDY_BIT (\d)", pins_h)
    assert (defs["RIG_ADS_RDY_PORT"].strip("'"), int(defs["RIG_ADS_RDY_BIT"])) == (rdy.group(1), int(rdy.group(2)))
    config = (repo_root / "firmware/config.h").read_text()
    assert int(defs["RIG_ADS1115_ADDRESS"], 16) == int(re.search(r"ADS1115_ADDRESS = (0x\w+)", config).group(1), 16)
    supply_mV = int(re.search(r"HEATER_SUPPLY_MV = (\d+)", config).group(1))
    assert SIMAVR_BENCH.simavr["heater_supply_V"] * 1000 == supply_mV
    conversion_us = re.search(r"MAX_CONVERSION_US = 612UL \* 1000000UL / (\d+)UL",
                              (repo_root / "firmware/drivers/cs5513.h").read_text())
    assert SIMAVR_BENCH.simavr["cs5513_conversion_us"] == 612 * 1_000_000 // int(conversion_us.group(1))


def test_moves_at_the_rate_limit_count_every_step_while_sampling(firmware_dir):
    """5 turns/s (16,000 steps/s, the firmware's limit) there and back while SAMPLEs
    stream at 10 ms: the A4988 sees every step with legal pulses, no slot is lost, the
    step train never runs dry mid-move (no underrun event, the QUEUE_STATUS count 0), and
    every SAMPLE's timestamp is the instant its ADS1115 conversion really started,
    within 100 us. (Before: the ring ran dry in the ramps above 12,800 steps/s, and the
    stamps were the scheduled times, up to 4 ms early.)"""
    with simavr_port(firmware_dir, trace=True) as (port, bench):
        ex = sc.Exchange(port, settle_s=0.05, first_reply_s=2.0)
        sc.handshake(ex)
        start = len(ex.received)
        ex.send(msg.SetSampling(1, 10_000))
        ex.send(msg.MoveTo(2, 16_000, 16_000, 320_000))
        ex.send(msg.MoveTo(3, -8_000, 16_000, 320_000))
        ex.wait_for(lambda m: isinstance(m, msg.Event) and m.kind == msg.EventKind.SEGMENT_DONE and m.segment == 3, 60,
                    since=start)
        ex.wait_device_s(0.1)
        qs = ex.send_for(msg.Heartbeat(), msg.QueueStatus)
    s = bench.summary
    assert s["steps"]["total"] == 16_000 + 24_000 and s["steps"]["position"] == -8_000
    assert s["steps"]["while_disabled"] == 0
    assert all(v == 0 for v in s["violations"].values()), s["violations"]
    assert s["steps"]["min_high_cycles"] >= 16 and s["steps"]["min_low_cycles"] >= 16   # >= 1 us at 16 MHz
    assert ex.samples[-1].step_position == -8_000
    assert all(b.counter == a.counter + 1 for a, b in zip(ex.samples, ex.samples[1:]))
    assert any(m.motor_moving for m in ex.samples)
    assert qs.step_underruns == 0 and not any(e.kind == msg.EventKind.STEP_UNDERRUN for e in ex.events)
    starts = sorted(float(line.split()[1]) for line in bench.trace_text.splitlines() if line.startswith("ads_start"))
    errors = [min(abs(smp.t_us - t) for t in starts) for smp in ex.samples]
    assert max(errors) <= 100, max(errors)
    assert s["isr"]["17"]["name"] == "TIMER1_COMPA" and s["isr"]["17"]["count"] >= 40_000
    assert s["twi"]["status_fixes"] > 0       # the simavr 1.6 SLA+W status quirk was met and handled
    assert s["adc"]["cs5513_sclk_violations"] == 0


def test_sigterm_stops_cleanly_with_a_summary(firmware_dir):
    with simavr_port(firmware_dir) as (port, bench):
        time.sleep(0.3)
    assert bench.returncode == 0
    assert bench.summary["stop_reason"] == "SIGTERM" and not bench.summary["crashed"]
    assert bench.summary["device_time_s"] > 0 and bench.summary["resets"] == 0


def test_a_lost_plant_stops_the_harness(firmware_dir):
    with simavr_port(firmware_dir) as (port, bench):
        ex = sc.Exchange(port, settle_s=0.05, first_reply_s=2.0)
        sc.handshake(ex)
        ex.send(msg.SetSampling(1, 20_000))
        bench.plant.close()                  # the next conversion finds no plant
        deadline = time.monotonic() + 20
        while bench._proc.poll() is None and time.monotonic() < deadline:
            try:
                ex.send(msg.Heartbeat())
            except (serial.SerialException, OSError):   # the harness closed the pty on its way out
                time.sleep(0.05)
    assert bench.returncode == 4
    assert "plant connection lost" in bench.summary["stop_reason"]


def test_a_crashing_firmware_is_reported(firmware_dir, tmp_path):
    """A program that runs off the end of flash: exit code 3, summary says crashed."""
    src = tmp_path / "crash.c"
    src.write_text("int main(void) { __asm__ volatile(\"jmp 0x3fffe\"); return 0; }\n")
    build = tmp_path / "build"
    build.mkdir()
    subprocess.run(["avr-gcc", "-mmcu=atmega2560", "-Os", str(src), "-o", str(build / "tsa_bench.elf")], check=True)
    (build / "tsa_simavr").symlink_to(firmware_dir / "build" / "tsa_simavr")
    with SimavrBench(SIMAVR_BENCH, SimavrSettings(firmware_dir=tmp_path, build=False, bootloader="none")) as bench:
        bench.start()
        deadline = time.monotonic() + 20
        while bench._proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
    assert bench.returncode == 3
    assert bench.summary["crashed"] and bench.summary["stop_reason"] == "firmware crashed"
    assert "crashed" in bench.stderr_text


@pytest.mark.parametrize("args, message", [
    ([], "--elf, --pty and --plant are required"),
    (["--elf", "/nonexistent.elf", "--pty", "/tmp/x", "--plant", "/tmp/y"], "cannot read firmware ELF"),
    (["--elf", "a", "--lead-ms"], "every option takes a value"),
])
def test_bad_arguments_are_refused_with_a_reason(firmware_dir, args, message):
    result = subprocess.run([str(firmware_dir / "build" / "tsa_simavr"), *args], capture_output=True, text=True)
    assert result.returncode == 2
    assert message in result.stderr


def test_summary_is_json_with_units_in_its_keys(firmware_dir):
    with simavr_port(firmware_dir) as (port, bench):
        pass
    s = bench.summary
    json.dumps(s)
    assert {"cycles", "device_time_s", "wall_time_s", "steps", "violations", "uart", "twi", "adc",
            "sample_interval", "isr"} <= set(s)
    assert s["f_cpu_hz"] == 16_000_000 and Path(s["elf"]).name == "tsa_bench.elf"


def test_sigterm_to_tsa_bench_run_aborts_and_stops_the_harness(repo_root, firmware_dir, tmp_path):
    """SIGTERM to `tsa-bench run` on simavr: STOP sent, file closed "aborted", the
    harness stopped with its summary printed."""
    import signal
    import sys

    from tsa_bench.store.reader import read_run

    out = tmp_path / "aborted.h5"
    proc = subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", "run", "configs/protocols/twist-sweep-3ply.yaml",
                             "--bench", "configs/bench/simavr.yaml", "--output", str(out)],
                            cwd=repo_root, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not (out.exists() and out.stat().st_size > 20_000) and time.monotonic() < deadline:
        time.sleep(0.2)
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stdout[-2000:] + stderr[-2000:]
    run = read_run(out)
    assert run.exit_status == "aborted" and run.attrs["backend"] == "simavr" and len(run) > 0
    assert "simavr " in stdout and "CRASHED" not in stdout


def _tiny_firmware(tmp_path, source: str, firmware_dir) -> Path:
    """A firmware_dir holding a tiny AVR program as the ELF and the real harness."""
    src = tmp_path / "tiny.c"
    src.write_text(source)
    build = tmp_path / "build"
    build.mkdir()
    subprocess.run(["avr-gcc", "-mmcu=atmega2560", "-O1", str(src), "-o", str(build / "tsa_bench.elf")], check=True)
    (build / "tsa_simavr").symlink_to(firmware_dir / "build" / "tsa_simavr")
    return tmp_path


def test_the_uart_overrun_a_real_chip_would_show_is_counted(firmware_dir, tmp_path):
    """A program that enables the receiver but never reads UDR0: of 10 bytes, 2 fit the
    real 2-level receive buffer and 8 overrun (simavr's own 64-byte FIFO would hide them)."""
    fw = _tiny_firmware(tmp_path, """#include <avr/io.h>
int main(void) { UBRR0 = 7; UCSR0A = 1 << U2X0; UCSR0C = 3 << UCSZ00; UCSR0B = (1 << RXEN0) | (1 << TXEN0);
  for (;;) {} }
""", firmware_dir)
    with SimavrBench(SIMAVR_BENCH, SimavrSettings(firmware_dir=fw, build=False, bootloader="none")) as bench:
        port = serial.Serial(bench.port_path, 250000, timeout=0.02)
        bench.start()
        time.sleep(0.2)
        port.write(bytes(range(10)))
        time.sleep(0.5)
        port.close()
    assert bench.summary["uart"]["rx_bytes"] == 2
    assert bench.summary["violations"]["uart_rx_overrun"] == 8


def test_step_pulses_too_short_and_dir_too_late_are_violations(firmware_dir, tmp_path):
    """STEP pulses of a few cycles (< 1 us) and DIR set one instruction before STEP rises
    (< 200 ns) are what the A4988 would not take: counted, while the steps still count."""
    fw = _tiny_firmware(tmp_path, """#include <avr/io.h>
int main(void) {
  DDRA = 0x07; PORTA = 0x00;                               /* /ENABLE low: driver on, DIR low */
  for (volatile unsigned char i = 0; i < 10; ++i) { PORTA |= 1; PORTA &= ~1; }
  PORTA |= 2; PORTA |= 1; PORTA &= ~1;                     /* DIR high right before STEP */
  for (;;) {} }
""", firmware_dir)
    with SimavrBench(SIMAVR_BENCH, SimavrSettings(firmware_dir=fw, build=False, bootloader="none")) as bench:
        bench.start()
        time.sleep(0.5)
    s = bench.summary
    assert s["steps"]["total"] == 11 and s["steps"]["position"] == -10 + 1
    assert s["violations"]["step_pulse_width"] >= 10
    assert s["violations"]["dir_setup"] == 1
    assert s["steps"]["min_high_cycles"] < 16
