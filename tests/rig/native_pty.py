"""The natively built firmware (firmware/native: the real core on a simulated board)
behind a pseudo-terminal, so a command can open it by path like a Mega's serial port."""

from __future__ import annotations

import os
import select
import subprocess
import threading
import tty
from pathlib import Path

from tsa_bench.protocol import MessageDecoder, msg
from tsa_bench.transport.pty_server import OpenWatch


class NativeFirmwarePty:
    """Starts the native firmware with its stdin and stdout on a pty's master side; the
    slave's path (:attr:`path`) is the port. The test keeps a slave descriptor open, so
    clients may come and go (no hang-up between commands). The firmware sends BOOT once,
    at start, as a Mega does after the DTR reset of the first open.

    ``as_hardware``: the firmware passes for the Mega (``--as-hardware``: no SIMULATED
    flag) and a relay thread stands between the pty and the firmware: every client's open
    of the port resets the core (``--control-fd`` "reset", as a Mega's DTR pulse does,
    :class:`~tsa_bench.transport.pty_server.OpenWatch`), and :meth:`hang` changes the load
    as a person would; ``reset_on_open=False`` is a Mega wired not to reset. :attr:`faults`
lists the latched faults the device reported, :attr:`proc` is the firmware process
(SIGSTOP stalls the rig)."""

    def __init__(self, binary: Path, *args: str, as_hardware: bool = False, reset_on_open: bool = True) -> None:
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        self.resets = 0
        self._relay: threading.Thread | None = None
        if not as_hardware:
            self.proc = subprocess.Popen([str(binary), *args], stdin=self.master, stdout=self.master,
                                         stderr=subprocess.PIPE, close_fds=True)
            return
        control_r, self._control = os.pipe()
        self.proc = subprocess.Popen([str(binary), *args, "--as-hardware", "--control-fd", str(control_r)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     pass_fds=(control_r,), bufsize=0)
        os.close(control_r)
        self._watch = OpenWatch(self.master, self._slave) if reset_on_open else None
        self.faults: list[int] = []    # each change of the latched fault the device reported (0: cleared)
        self._decoder = MessageDecoder()
        self._stop = threading.Event()
        self._relay = threading.Thread(target=self._run_relay, daemon=True)
        self._relay.start()

    def hang(self, grams: float) -> None:
        """A person hangs ``grams`` on the TSA."""
        os.write(self._control, f"load {grams:g}\n".encode())

    def _run_relay(self) -> None:
        out = self.proc.stdout.fileno()
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master, out], [], [], 0.05)
            try:
                if self.master in ready:
                    data = os.read(self.master, 4096)
                    opened, data = self._watch.split(data) if self._watch is not None else (False, data)
                    if opened:
                        self.resets += 1
                        os.write(self._control, b"reset\n")
                    if data:
                        self.proc.stdin.write(data)
                if out in ready:
                    data = os.read(out, 4096)
                    if not data:
                        return
                    self._note_faults(data)
                    os.write(self.master, data)
            except OSError:
                return

    def _note_faults(self, data: bytes) -> None:
        for frame in self._decoder.feed(data):
            m = frame.message
            code = m.fault if isinstance(m, msg.QueueStatus) else m.code if isinstance(m, msg.Event) and \
                m.kind == msg.EventKind.FAULT else None
            if code is not None and code != (self.faults[-1] if self.faults else 0):
                self.faults.append(code)

    def close(self) -> None:
        if self._relay is not None:
            self._stop.set()
            self._relay.join(5)
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(10)
        for fd in (self.master, self._slave) + ((self._control,) if self._relay is not None else ()):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> "NativeFirmwarePty":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
