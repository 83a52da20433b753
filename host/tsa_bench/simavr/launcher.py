"""Start and stop the firmware-in-the-loop bench: the simavr harness plus its plant.

Units: times in s unless a name says ms or us.

Contract: :class:`SimavrBench` is a context manager. Entering it builds the firmware
ELF and the harness (``make -C <firmware_dir> harness``, a no-op when up to date),
starts a :class:`~tsa_bench.simavr.plant_server.PlantServer` on a Unix socket in a
private temporary directory, starts ``tsa_simavr`` on a pty in that directory and
waits for it to connect. The caller then opens :attr:`port_path` like any serial
port and calls :meth:`start`, which powers the AVR up (as plugging in a real Mega and
opening its port does): the emulated stk500v2 bootloader runs ~1 s, then the device's
BOOT frame follows. :meth:`reset` is the DTR pulse of a host opening the port again (an
external reset, SIGUSR1 to the harness). Leaving the context sends SIGTERM, waits for
the harness to write its JSON summary (:attr:`summary`) and removes the directory.
Failures raise :class:`SimavrError` with what to check.

The rig's settings (the ``simavr:`` section of a bench file, or SimavrSettings, both in
:mod:`tsa_bench.bench.simavr_section`):
``bootloader`` stock | 2011 | none (the 2011 release loops after a watchdog reset),
``enable_pull`` down | up (the A4988 /ENABLE resistor: down keeps the motor energized
through a reset), ``backdrive_steps_per_s`` (how fast the loaded strings turn a released
motor back), ``ads_rate_error`` (the ADS1115's oscillator error, +-0.1 in its data
sheet); tests add ``twi_faults`` (firmware/sim/twi_bus.c), ``rdy_cuts`` (the ALERT/RDY
wire cut between T0[:T1] s: firmware/sim/ads1115.c), ``hang_at_s`` (with ``hang_masked``)
and ``trace``. :meth:`SimavrBench.brown_out` dips the supply: SRAM kept, MCUSR BORF (the
stock bootloader clears it), the A4988's translator back at Home.
"""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import tempfile
from pathlib import Path
from typing import Any

from tsa_bench.bench.simavr_section import SimavrSettings
from tsa_bench.benchdata import BenchConfig
from tsa_bench.simavr.plant_server import PlantServer

__all__ = ["SimavrBench", "SimavrError"]


class SimavrError(RuntimeError):
    """The firmware-in-the-loop bench could not be built, started or stopped cleanly."""


class SimavrBench:
    """The firmware ELF running in simavr on a pty, coupled to the Python plant."""

    def __init__(self, bench: BenchConfig, settings: SimavrSettings, seed: int | None = None,
                 connect_timeout_s: float = 20.0) -> None:
        self.bench = bench
        self.settings = settings
        self.seed = seed
        self.connect_timeout_s = connect_timeout_s
        self.summary: dict[str, Any] | None = None
        self.trace_text: str | None = None
        self.returncode: int | None = None
        self.stderr_text = ""
        self._dir: Path | None = None
        self._proc: subprocess.Popen | None = None
        self.plant: PlantServer | None = None

    @property
    def port_path(self) -> str:
        assert self._dir is not None, "use SimavrBench as a context manager"
        return str(self._dir / "tty")

    def build(self) -> None:
        result = subprocess.run(["make", "-C", str(self.settings.firmware_dir), "--no-print-directory", "-s",
                                 "harness"], capture_output=True, text=True)
        if result.returncode != 0:
            raise SimavrError(
                f"building the firmware and the simavr harness in {self.settings.firmware_dir} failed "
                f"(install the toolchain: bash scripts/setup-firmware-toolchain.sh):\n"
                + (result.stdout + result.stderr)[-3000:])

    def __enter__(self) -> "SimavrBench":
        s = self.settings
        if s.build:
            self.build()
        for path in (s.elf, s.harness, *([s.bootloader_elf] if s.bootloader_elf else [])):
            if not path.exists():
                raise SimavrError(f"{path} does not exist: run `make -C {s.firmware_dir} harness`")
        self._dir = Path(tempfile.mkdtemp(prefix="tsa-simavr-"))
        try:
            self.plant = PlantServer(self.bench, str(self._dir / "plant.sock"), s.heater_supply_V, seed=self.seed)
            cmd = [str(s.harness), "--elf", str(s.elf), "--pty", self.port_path,
                   "--plant", self.plant.path, "--summary", str(self._dir / "summary.json"),
                   "--lead-ms", repr(s.lead_ms), "--host-gone-ms", repr(s.host_gone_ms),
                   "--realtime", repr(s.realtime_factor), "--cs5513-conversion-us", repr(s.cs5513_conversion_us),
                   "--bootloader", str(s.bootloader_elf or "none"), "--enable-pull", s.enable_pull,
                   "--backdrive-steps-per-s", repr(s.backdrive_steps_per_s),
                   "--ads-rate-error", repr(s.ads_rate_error)]
            for fault in s.twi_faults:
                cmd += ["--twi-fault", fault]
            for cut in s.rdy_cuts:
                cmd += ["--rdy-cut", cut]
            if s.hang_at_s is not None:
                cmd += ["--hang-at", repr(s.hang_at_s), "--hang-masked", "1" if s.hang_masked else "0"]
            if s.trace:
                cmd += ["--trace", str(self._dir / "trace.txt")]
            self._stderr = open(self._dir / "stderr.txt", "w+")
            self._proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=self._stderr)
            try:
                self.plant.wait_connected(self.connect_timeout_s)
            except (TimeoutError, ConnectionError) as exc:
                code = self._proc.poll()
                raise SimavrError(f"{exc}; harness exit code {code}: {self._read_stderr()}") from None
        except BaseException:
            self.close()
            raise
        return self

    def start(self) -> None:
        """Release the AVR from reset; its BOOT frame follows on the pty."""
        assert self.plant is not None
        self.plant.start()

    def reset(self) -> None:
        """The DTR pulse of a host opening the port again: an external reset of the AVR."""
        assert self._proc is not None
        self._proc.send_signal(signal.SIGUSR1)

    def brown_out(self) -> None:
        """A supply dip: the AVR resets with BORF and SRAM kept, the A4988 restarts at Home."""
        assert self._proc is not None
        self._proc.send_signal(signal.SIGUSR2)

    def set_load_g(self, load_g: float) -> None:
        assert self.plant is not None
        self.plant.set_load_g(load_g)

    def _read_stderr(self) -> str:
        try:
            self._stderr.flush()
            return (self._dir / "stderr.txt").read_text()[-2000:].strip()  # type: ignore[operator]
        except (OSError, AttributeError, TypeError):
            return ""

    def close(self) -> None:
        """Stop the harness (SIGTERM), collect its summary, remove the directory."""
        if self._proc is not None and self._proc.poll() is None:
            self._proc.send_signal(signal.SIGTERM)
            try:
                self._proc.wait(15)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait(5)
        if self._proc is not None:
            self.returncode = self._proc.returncode
        if self.plant is not None:
            self.plant.close()
        if self._dir is not None:
            summary = self._dir / "summary.json"
            if summary.exists():
                self.summary = json.loads(summary.read_text())
            trace = self._dir / "trace.txt"
            if trace.exists():
                self.trace_text = trace.read_text()
            self.stderr_text = self._read_stderr()
            self._stderr.close()
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None

    def __exit__(self, *exc: object) -> None:
        self.close()
