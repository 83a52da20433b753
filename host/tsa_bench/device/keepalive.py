"""The device's watchdog fed from a thread of its own, whatever the owner's thread does.

Units: wall time in s.

Contract of :class:`Keepalive` (for a device on a real line or a pty; ``sim://`` in this
process keeps time with the host's reads and needs none): while running, a daemon thread
sends HEARTBEAT through :meth:`BenchClient.send_keepalive` whenever nothing has been sent
for ``period_s``, so a thread that owns the session and is busy (a slow flush, a slow
consumer, a loaded machine) cannot starve the device's watchdog. It is a keepalive of a
host that is alive, not of a process that has hung: once the owner has not read the port
for ``max_stall_s`` it stops (the device's watchdog then stops motor and heater, as for a
host that went away), except while the owner says it waits for a person
(:meth:`attended`: an operator prompt may take minutes). :meth:`stop` ends the thread
and waits for it; the object is a context manager that always stops it.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from types import TracebackType

from tsa_bench.device.client import BenchClient

#: Longest the owner may go without reading the port before keepalives stop (s).
MAX_STALL_S = 30.0


class Keepalive:
    """HEARTBEAT on a thread of its own (see the module contract)."""

    def __init__(self, client: BenchClient, period_s: float, max_stall_s: float | None = None) -> None:
        max_stall_s = MAX_STALL_S if max_stall_s is None else max_stall_s
        if period_s <= 0 or max_stall_s <= 0:
            raise ValueError(f"period_s and max_stall_s must be positive, got {period_s} and {max_stall_s}")
        self.client, self.period_s, self.max_stall_s = client, period_s, max_stall_s
        self.sent = 0            # keepalives sent
        self.checks = 0          # times the thread looked whether one was due
        self.errors: list[str] = []   # why sending failed (the owner sees a lost line itself)
        self._attended = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> Keepalive:
        if self._thread is None:
            self._thread = threading.Thread(target=self._loop, name="tsa-bench keepalive", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """End the thread and wait for it (at most one port timeout plus one check)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    @contextmanager
    def attended(self) -> Iterator[None]:
        """The owner waits for a person: keep the device alive however long it takes."""
        self._attended += 1
        try:
            yield
        finally:
            self._attended -= 1
            self.client.last_read_wall = time.monotonic()   # the stall clock restarts now

    def _loop(self) -> None:
        check_s = self.period_s / 4
        while not self._stop.wait(check_s):
            self.checks += 1
            if not self._attended and time.monotonic() - self.client.last_read_wall > self.max_stall_s:
                continue   # the owner is stuck: let the device's watchdog act
            try:
                self.sent += self.client.send_keepalive(self.period_s)
            except Exception as exc:   # a lost line: the owner finds out on its next read or write
                self.errors.append(f"{type(exc).__name__}: {exc}")
                return

    def __enter__(self) -> Keepalive:
        return self.start()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.stop()
