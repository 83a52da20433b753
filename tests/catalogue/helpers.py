"""Runs made for the catalogue and lab tests: a short protocol, the CLI in a process, waiting on conditions."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "host")}

#: ~70 s of device time: a load variable, a prompt, cycles (the lifetime protocol's shape, shorter).
SHORT = """name: short-life
variables: {load_g: 300}
load_g: $load_g
sampling_period_s: 0.1
defaults: {rate_turns_per_s: 3.33, accel_turns_per_s2: 50}
steps:
  - move_to: {turns: 0}
  - prompt: {text: "Hang $load_g g on the untwisted TSA", load_g: $load_g}
  - move_to: {turns: 15}
  - hold: {duration_s: 10}
  - repeat:
      count: 3
      steps:
        - rotation_sequence: {targets_turns: [17, 19, 21, 19, 17, 15], hold_s: 1}
  - move_to: {turns: 0}
  - hold: {duration_s: 5}
"""


def short_protocol(folder: Path) -> Path:
    path = folder / "short-life.yaml"
    path.write_text(SHORT)
    return path


def cli(*args: str, cwd: Path | None = None, **kw) -> subprocess.CompletedProcess:
    """``tsa-bench ARGS`` in a process of its own (real signals, real exit)."""
    return subprocess.run([sys.executable, "-m", "tsa_bench.cli", *args], capture_output=True, text=True, env=ENV,
                          cwd=cwd or ROOT, timeout=600, **kw)


def start_cli(*args: str, cwd: Path | None = None, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=ENV, cwd=cwd or ROOT, **kw)


def wait_for(condition: Callable[[], object], what: str, timeout_s: float = 120.0) -> object:
    """The condition's first true value; fails the test after ``timeout_s`` (a generous deadline)."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def live_samples(run_file: Path) -> int:
    """Samples the live sidecar of a run being recorded holds (0 before it appears)."""
    from tsa_bench.store.live import LiveFormatError, LiveTail, sidecar_path

    side = sidecar_path(run_file)
    if not side.is_file():
        return 0
    try:
        tail = LiveTail(side)
    except (LiveFormatError, OSError):
        return 0
    try:
        return len(tail.poll())
    finally:
        tail.close()
