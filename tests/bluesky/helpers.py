"""What the Bluesky tests share: a RunEngine that keeps its documents, a simulated rig,
the same twist scan as a YAML protocol, the native firmware behind a recording relay."""

from __future__ import annotations

import math
import subprocess
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from bluesky import RunEngine
from ophyd_async.core import init_devices

from tests.faults.relay import LinkFaults, PtyRelay
from tests.rig.native_pty import NativeFirmwarePty
from tsa_bench.bluesky import TsaRig

ROOT = Path(__file__).resolve().parents[2]
SCAN_TURNS = [0, 5, 10, 15, 20, 25, 30, 35, 40]
#: The twist scan of the equivalence test as a protocol: same load, rate, acceleration,
#: sampling period, and a hold as long as the rig's integration time after each move.
SCAN_PROTOCOL = """\
name: twist-scan
load_g: 200
sampling_period_s: 0.1
limits: {max_heater_voltage_V: 0}
defaults: {rate_turns_per_s: 3.33, accel_turns_per_s2: 50}
steps:
  - rotation_sequence: {targets_turns: [0, 5, 10, 15, 20, 25, 30, 35, 40], hold_s: 0.5}
"""


class Recorder:
    """A RunEngine callback keeping every (name, document)."""

    def __init__(self) -> None:
        self.docs: list[tuple[str, dict]] = []

    def __call__(self, name: str, doc: dict) -> None:
        self.docs.append((name, doc))

    def of(self, name: str) -> list[dict]:
        return [d for n, d in self.docs if n == name]

    def events(self) -> list[dict]:
        return self.of("event")


def make_re() -> tuple[RunEngine, Recorder]:
    re, rec = RunEngine({}), Recorder()
    re.subscribe(rec)
    return re, rec


def connect(port: str, bench: str | Path | None = None, **kw) -> TsaRig:
    with init_devices():
        rig = TsaRig(port, bench=bench, **kw)
    return rig


def record_commands(rig: TsaRig, monkeypatch) -> list[str]:
    """The type names of every command the rig's device client sends from now on, in order."""
    sent: list[str] = []
    client = rig.session.link.client
    original = client.command

    def command(message, *, check=True):
        sent.append(type(message).__name__)
        return original(message, check=check)

    monkeypatch.setattr(client, "command", command)
    return sent


def fsum_mean(values) -> float:
    """The mean of the finite values (NaN when none): the reduction a reading reports."""
    finite = [float(v) for v in values if v == v]
    return math.fsum(finite) / len(finite) if finite else math.nan


def quick_bench(tmp: Path, name: str) -> Path:
    """A shipped bench file with a short boot wait (a pty client never sees the BOOT)."""
    path = tmp / f"quick-{name}"
    path.write_text((ROOT / "configs/bench" / name).read_text().replace("boot_timeout_s: 3.0", "boot_timeout_s: 0.2"))
    return path


def build_native() -> Path:
    built = subprocess.run(["make", "-C", "firmware", "native"], cwd=ROOT, capture_output=True, text=True)
    assert built.returncode == 0, built.stdout + built.stderr
    return ROOT / "firmware/build/tsa_bench_native"


@contextmanager
def native_relay(*args: str) -> Iterator[PtyRelay]:
    """The native firmware behind a pty, a recording relay in front (host side: ``.path``)."""
    with NativeFirmwarePty(build_native(), *args) as fw:
        relay = PtyRelay(fw.path, LinkFaults())
        try:
            yield relay
        finally:
            relay.close()
