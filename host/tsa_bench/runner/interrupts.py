"""Ctrl-C and SIGTERM during a run: never lost, never in the middle of a write.

Contract of :class:`Interrupts`: once installed (main thread only) it replaces the
SIGINT and SIGTERM handlers. A signal only counts (``count``); the runner calls
:meth:`check` at safe points (between reads, between commands, while waiting for an
ACK) and that raises KeyboardInterrupt once a signal has arrived, so a file flush or
the STOP sequence is never cut in half: rows are appended whole, the STOP is always
sent, the file is always closed. Inside :meth:`immediate` (a blocking wait such as an
operator prompt) the first signal raises at once instead. After :meth:`stopping`
nothing raises any more: a second signal only asks to hurry (:attr:`hurry`), which
the runner honours by skipping what it may skip (waiting for the last samples), never
the STOP or the close. :meth:`restore` puts the previous handlers back.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupts:
    """Deferred SIGINT/SIGTERM for one run (module contract)."""

    def __init__(self) -> None:
        self.count = 0
        self.last_signal: int | None = None
        self._immediate = 0
        self._stopping = False
        self._previous: dict[int, object] = {}

    @property
    def installed(self) -> bool:
        return bool(self._previous)

    def install(self) -> bool:
        """Take over SIGINT and SIGTERM; False (nothing done) outside the main thread."""
        if self.installed or threading.current_thread() is not threading.main_thread():
            return False
        for sig in SIGNALS:
            self._previous[sig] = signal.signal(sig, self._on_signal)
        return True

    def restore(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)  # type: ignore[arg-type]
        self._previous.clear()

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self.count += 1
        self.last_signal = signum
        if self.count == 1 and self._immediate and not self._stopping:
            raise KeyboardInterrupt

    @property
    def requested(self) -> bool:
        """A signal has arrived."""
        return self.count > 0

    @property
    def hurry(self) -> bool:
        """More than one signal: finish as fast as safety allows."""
        return self.count > 1

    def check(self) -> None:
        """Raise KeyboardInterrupt at a safe point when a signal has arrived (not once stopping)."""
        if self.count and not self._stopping:
            raise KeyboardInterrupt

    def stopping(self) -> None:
        """From now on (STOP, flush, close) signals only count."""
        self._stopping = True

    @contextmanager
    def immediate(self) -> Iterator[None]:
        """A blocking wait that the first signal breaks at once (KeyboardInterrupt)."""
        self.check()
        self._immediate += 1
        try:
            yield
        finally:
            self._immediate -= 1
