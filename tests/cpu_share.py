"""Firmware tests run alone on two workers: a readers-writer lock over the test run.

The native firmware and simavr keep wall-clock time (the device's 2 s watchdog, the
bootloader's wait, real-time sampling). On a loaded machine the other pytest worker would
starve them beyond what a serial run does, so a firmware test (:data:`tests.conftest.FIRMWARE_GROUP`)
takes the lock exclusively and any other test takes it shared: ordinary tests run side by
side, a firmware test runs with the other worker paused. A turnstile taken first by both
keeps a waiting firmware test from being starved by a stream of shared holders.
``fcntl.flock`` locks belong to an open file, so the lock works between processes and
between threads that open the files separately.
"""

from __future__ import annotations

import fcntl
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def cpu_share(folder: Path, exclusive: bool) -> Iterator[None]:
    """Hold the run's lock in ``folder``: alone (``exclusive``) or beside other shared holders."""
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "turnstile.lock", "a+") as turnstile, open(folder / "cpu.lock", "a+") as cpu:
        fcntl.flock(turnstile, fcntl.LOCK_EX)
        try:
            fcntl.flock(cpu, fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH)
        finally:
            fcntl.flock(turnstile, fcntl.LOCK_UN)
        try:
            yield
        finally:
            fcntl.flock(cpu, fcntl.LOCK_UN)
