"""The natively built firmware (firmware/native: the real core on a simulated board)
behind a pseudo-terminal, so a command can open it by path like a Mega's serial port."""

from __future__ import annotations

import os
import subprocess
import tty
from pathlib import Path


class NativeFirmwarePty:
    """Starts the native firmware with its stdin and stdout on a pty's master side; the
    slave's path (:attr:`path`) is the port. The test keeps a slave descriptor open, so
    clients may come and go (no hang-up between commands). The firmware sends BOOT once,
    at start, as a Mega does after the DTR reset of the first open."""

    def __init__(self, binary: Path, *args: str) -> None:
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        self.proc = subprocess.Popen([str(binary), *args], stdin=self.master, stdout=self.master,
                                     stderr=subprocess.PIPE, close_fds=True)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(10)
        for fd in (self.master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> "NativeFirmwarePty":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
