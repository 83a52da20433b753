"""`make flash` through the Arduino Mega's own stk500v2 bootloader, on the emulated Mega
(simavr running Debian's stk500boot_v2_mega2560.hex at the boot section, the port as the
Mega's USB-serial chip: opening it resets the AVR, baud rates matter). The commands are
read from firmware/README.md's "Flashing" section, so the documented command is the one
tested: a wrong programmer type or baud rate there or in the Makefile fails here as on a
board. Each test waits on conditions; the subprocess time-outs only guard against hangs."""

from __future__ import annotations

import re
import select
import shlex
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import serial
import yaml

from tests import conformance_scenarios as sc
from tests.simavr.conftest import ROOT, SIMAVR_BENCH, wait_boot
from tsa_bench.bench.simavr_section import MEGA_BOOTLOADER_HEX, SimavrSettings
from tsa_bench.protocol import MessageDecoder, msg
from tsa_bench.simavr import SimavrBench, mega_settings
from tsa_bench.store.reader import read_run

FIRMWARE = ROOT / "firmware"
DOC_PORT = "/dev/ttyACM0"
HANG_GUARD_S = 300      # a subprocess that takes longer than this is hung, not slow

SHORT_PROTOCOL = """\
name: flash-smoke
description: one turn out and back with a second's hold, no heat (the first run on a freshly flashed Mega)
load_g: 100
sampling_period_s: 0.1
limits: {max_twist_turns: 2, max_heater_voltage_V: 0}
defaults: {rate_turns_per_s: 2, accel_turns_per_s2: 20}
steps:
  - heater: {voltage_V: 0}
  - move_to: {turns: 1}
  - hold: {duration_s: 1}
  - move_to: {turns: 0}
"""

# An older application: says so at 250000 baud, forever (the bootloader may leave U2X set).
OLDER_APP = r"""
#include <avr/io.h>
int main(void) {
    UCSR0A = 0;
    UBRR0 = 3;
    UCSR0B = 1 << TXEN0;
    for (;;)
        for (const char *p = "older firmware\n"; *p; ++p) {
            while (!(UCSR0A & (1 << UDRE0))) {}
            UDR0 = *p;
        }
}
"""


def documented() -> tuple[list[str], list[str]]:
    """(make arguments, avrdude command) from firmware/README.md's "Flashing" section."""
    text = (FIRMWARE / "README.md").read_text()
    section = text.split("### Flashing", 1)[1].split("\n## ", 1)[0]
    make_line = re.search(r"^make (flash PORT=\S+)$", section, re.M)
    avrdude_line = re.search(r"^avrdude .*$", section, re.M)
    assert make_line and avrdude_line, "firmware/README.md's Flashing section lost its commands"
    assert f"PORT={DOC_PORT}" in make_line.group(1) and f" -P {DOC_PORT} " in avrdude_line.group(0)
    return shlex.split(make_line.group(1)), shlex.split(avrdude_line.group(0))


def on_port(args: list[str], port: str, **subst: str) -> list[str]:
    """The documented arguments with the emulated Mega's port (and other words) put in."""
    out = []
    for a in args:
        a = a.replace(DOC_PORT, port)
        for old, new in subst.items():
            a = a.replace(old, new)
        out.append(a)
    return out


def hex_data_bytes(path: Path) -> int:
    return sum(int(line[1:3], 16) for line in path.read_text().split() if line[7:9] == "00")


@pytest.fixture(scope="module")
def mega_ready(firmware_dir):
    """The Mega's bootloader, avrdude and build/tsa_bench.hex; a skip only where Debian's
    arduino-core-avr cannot be installed (no such package), a failure where it could be."""
    if not MEGA_BOOTLOADER_HEX.exists():
        known = shutil.which("apt-cache") and subprocess.run(
            ["apt-cache", "show", "arduino-core-avr"], capture_output=True).returncode == 0
        if not known:
            pytest.skip("Debian's arduino-core-avr (the Mega's stk500v2 bootloader) cannot be installed on this "
                        "machine: apt knows no such package")
        pytest.fail(f"{MEGA_BOOTLOADER_HEX} is missing: install arduino-core-avr "
                    "(bash scripts/setup-firmware-toolchain.sh)")
    assert shutil.which("avrdude"), "avrdude is missing: bash scripts/setup-firmware-toolchain.sh"
    result = subprocess.run(["make", "-C", str(FIRMWARE), "-s", "all"], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    return firmware_dir


def flash(args: list[str]) -> subprocess.CompletedProcess:
    """Run a documented command (make or avrdude) in firmware/, as a lab would."""
    return subprocess.run(args, cwd=FIRMWARE, capture_output=True, text=True, timeout=HANG_GUARD_S)


def cli(*args: str, stdin: str = "") -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tsa_bench.cli", *args], cwd=ROOT, input=stdin,
                          capture_output=True, text=True, timeout=HANG_GUARD_S)


def test_the_readme_avrdude_command_is_what_make_flash_runs():
    """The avrdude line documented for machines without make is the Makefile's, word for word."""
    make_args, avrdude = documented()
    result = subprocess.run(["make", "-n", "-C", str(FIRMWARE), *make_args], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    run = [shlex.split(line) for line in result.stdout.splitlines() if line.startswith("avrdude ")]
    assert run == [avrdude]


def test_sim_serve_mega_is_flashed_by_the_documented_command_and_runs_a_protocol(mega_ready, tmp_path):
    """A blank emulated Mega from `tsa-bench sim-serve --mega`: the README's `make flash`
    programs and verifies build/tsa_bench.hex through the real bootloader, which then
    starts it; `tsa-bench check` and a protocol `run` talk to the firmware just flashed."""
    make_args, _ = documented()
    # Ctrl-C reaches it as in a terminal's foreground, even when the suite runs with SIGINT ignored
    # (a background job): an ignored SIGINT would leave sim-serve, and its harness, running
    proc = subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", "sim-serve", "--mega", "--seed", "1"],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 120)
        port = proc.stdout.readline().strip() if ready else ""
        assert port.endswith("/tty"), f"sim-serve --mega printed no port: {proc.poll()} {port!r}"

        result = flash(["make", *on_port(make_args, port)])
        out = result.stdout + result.stderr
        assert result.returncode == 0, out[-3000:]
        n = hex_data_bytes(FIRMWARE / "build" / "tsa_bench.hex")
        assert f"{n} bytes of flash written" in out and f"{n} bytes of flash verified" in out, out[-3000:]

        # the lab's bench file with generous host timeouts: on a busy machine the emulated
        # Mega falls behind wall-clock pace (its bootloader's 0.83 s may take several)
        bench = yaml.safe_load((ROOT / "configs" / "bench" / "arduino-mega.yaml").read_text())
        bench.update(boot_timeout_s=120.0, ack_timeout_s=5.0)
        bench_file = tmp_path / "mega-busy-host.yaml"
        bench_file.write_text(yaml.safe_dump(bench))
        result = cli("check", "--port", port, "--bench", str(bench_file), "--seconds", "1")
        assert result.returncode == 0, result.stdout + result.stderr
        assert "tsa-bench firmware" in result.stdout and "(matches this host)" in result.stdout
        # sensors read; a firmware just flashed has no twist zero yet, and check says so
        assert "check: position unknown, sensors read" in result.stdout, result.stdout

        protocol = tmp_path / "flash-smoke.yaml"
        protocol.write_text(SHORT_PROTOCOL)
        out_file = tmp_path / "first.h5"
        # the operator confirms the twist zero, as at a real bench after a power-up
        result = cli("run", str(protocol), "--port", port, "--bench", str(bench_file), "--output", str(out_file),
                     stdin="y\n")
        assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
        run = read_run(out_file)
        assert run.exit_status == "success" and run.attrs["backend"] == "serial"
        assert [k.decode() if isinstance(k, bytes) else k for k in run.segments["kind"]] == ["heater", "move", "hold", "move"]
        assert run.segments["completed"].all()
        assert abs(max(run.samples["turns"]) - 1.0) < 1e-6 and len(run.samples["turns"]) >= 10
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, proc.stderr.read()[-2000:]
    assert not Path(port).parent.exists()


def _read_until(port: serial.Serial, want: bytes, timeout_s: float = 60) -> bytes:
    got, deadline = b"", time.monotonic() + timeout_s
    while want not in got and time.monotonic() < deadline:
        got += port.read(256)
    return got


def _read_until_quiet(port: serial.Serial, quiet_s: float = 0.5, timeout_s: float = 60) -> bytes:
    """Bytes from the first one on until none came for ``quiet_s`` (the device's BOOT is out)."""
    got, deadline = b"", time.monotonic() + timeout_s
    while not got and time.monotonic() < deadline:
        got += port.read(256)
    last = time.monotonic()
    while time.monotonic() - last < quiet_s:
        chunk = port.read(256)
        if chunk:
            got, last = got + chunk, time.monotonic()
    return got


def test_an_update_over_an_older_firmware_and_a_watchdog_reset_after_it(mega_ready, tmp_path):
    """The documented avrdude command flashes an older program, which runs; `make flash`
    then updates it to the firmware, whose BOOT follows when the host opens the port. A
    host at the wrong baud rate reads no frame. A hang with interrupts masked ends in a
    hardware watchdog reset, after which the firmware boots again and answers: no reset
    loop. Debian's bootloader clears MCUSR and the watchdog, then calls the application
    with EIND = 1 (its C start-up's value): the call lands at 0x20000, in erased flash,
    and the chip runs on into the bootloader, which waits as after any reset. The
    stand-in (sim/boot/) waits as long."""
    make_args, avrdude = documented()
    src = tmp_path / "older.c"
    src.write_text(OLDER_APP)
    older = tmp_path / "older.hex"
    subprocess.run(["avr-gcc", "-mmcu=atmega2560", "-Os", str(src), "-o", str(tmp_path / "older.elf")], check=True)
    subprocess.run(["avr-objcopy", "-O", "ihex", str(tmp_path / "older.elf"), str(older)], check=True)
    settings = mega_settings(SimavrSettings(firmware_dir=mega_ready, build=False, hang_masked=True))
    with SimavrBench(SIMAVR_BENCH, settings, seed=1) as mega:
        mega.start()
        result = flash(on_port(avrdude, mega.port_path, **{"build/tsa_bench.hex": str(older)}))
        assert result.returncode == 0 and "bytes of flash verified" in result.stderr, result.stderr[-3000:]
        with serial.Serial(mega.port_path, 250000, timeout=0.05) as port:     # opening it resets the Mega
            assert b"older firmware\n" in _read_until(port, b"older firmware\n")

        result = flash(["make", *on_port(make_args, mega.port_path)])
        assert result.returncode == 0 and "bytes of flash verified" in result.stderr, result.stderr[-3000:]

        with serial.Serial(mega.port_path, 115200, timeout=0.05) as port:     # the wrong rate
            got = _read_until_quiet(port)
            assert got, "nothing at all arrived at the wrong baud rate"
            assert not MessageDecoder().feed(got), got

        with serial.Serial(mega.port_path, 250000, timeout=0.05) as port:
            ex = sc.Exchange(port, settle_s=0.08, first_reply_s=2.0)
            wait_boot(ex, 0)
            sc.handshake(ex)
            since = len(ex.received)
            mega.hang()
            wait_boot(ex, since)       # the host keeps quiet, as after opening the port
            ident = ex.send_for(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH), msg.Identity)
            assert ident.catalogue_hash == msg.CATALOGUE_HASH
    log = mega.summary["reset_log"]
    causes = [r["cause"] for r in log]
    assert causes[-3:] == ["hang_injected_masked", "watchdog", "erased_flash"], causes   # one reset, no loop
    assert causes.count("watchdog") == 1 and not mega.summary["crashed"]
    # the wait from each reset to the application's start, against the stand-in's
    stand_in = (FIRMWARE / "sim" / "boot" / "sim_bootloader.c").read_text()
    stand_in_s = int(re.search(r"#define BOOT_WAIT_CYCLES (\d+)UL", stand_in).group(1)) / 16e6
    resets = [r["t_s"] for r in log if r["cause"] in ("external", "watchdog")]
    starts = mega.summary["app_start_s"]
    for kind, t_reset in (("the port's opening", resets[-2]), ("the watchdog reset", resets[-1])):
        wait_s = min(t for t in starts if t > t_reset) - t_reset
        assert abs(wait_s / stand_in_s - 1) < 0.02, f"after {kind}: {wait_s:.4f} s, stand-in {stand_in_s:.4f} s"


def test_a_damaged_bootloader_hex_is_refused_with_its_line(mega_ready, tmp_path):
    """A hex file with a bad checksum (a broken download, a hand edit) is not half loaded."""
    lines = MEGA_BOOTLOADER_HEX.read_text().splitlines()
    lines[2] = lines[2][:-2] + ("00" if lines[2][-2:] != "00" else "01")
    bad = tmp_path / "damaged.hex"
    bad.write_text("\n".join(lines) + "\n")
    harness = mega_ready / "build" / "tsa_simavr"
    result = subprocess.run([str(harness), "--elf", "blank", "--pty", str(tmp_path / "tty"), "--plant",
                             str(tmp_path / "plant.sock"), "--bootloader", str(bad)], capture_output=True, text=True)
    assert result.returncode == 2
    assert f"{bad} line 3: a bad checksum" in result.stderr
