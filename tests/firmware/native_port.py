"""A pyserial-like port onto the natively built firmware (firmware/native), which runs
the real core Device on a simulated board and speaks the protocol on stdin/stdout."""

from __future__ import annotations

import os
import select
import subprocess
from pathlib import Path


class NativeFirmwarePort:
    """Starts the native firmware binary; ``read``/``write`` like a serial port."""

    def __init__(self, binary: Path, *args: str, timeout: float = 0.05) -> None:
        self.proc = subprocess.Popen([str(binary), *args], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, bufsize=0)
        self.timeout = timeout
        self.port = f"native:{binary.name}"
        self.baudrate = 250000
        self._fd = self.proc.stdout.fileno()
        os.set_blocking(self._fd, False)
        self._rx = bytearray()

    def _fill(self, wait_s: float) -> None:
        ready, _, _ = select.select([self._fd], [], [], wait_s)
        if ready:
            try:
                chunk = os.read(self._fd, 65536)
            except BlockingIOError:
                chunk = b""
            if not chunk and self.proc.poll() is not None:
                raise OSError(f"native firmware exited with {self.proc.returncode}: "
                              f"{self.proc.stderr.read().decode(errors='replace')[-2000:]}")
            self._rx += chunk

    @property
    def in_waiting(self) -> int:
        if not self._rx:
            self._fill(0)
        return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        if not self._rx:
            self._fill(self.timeout)
        data = bytes(self._rx[:size])
        del self._rx[:size]
        return data

    def write(self, data: bytes) -> int:
        self.proc.stdin.write(data)
        self.proc.stdin.flush()
        return len(data)

    def reset_input_buffer(self) -> None:
        self._fill(0)
        self._rx.clear()

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(5)
