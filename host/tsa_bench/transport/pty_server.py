"""Serve a simulated bench device on a pseudo-terminal, so any serial client can use it.

Units: virtual and wall time in s; ``speed`` is virtual s per wall s (None or 0 = as
fast as possible).

Contract: :func:`serve_pty` opens a pty pair, puts the slave in raw mode (no echo, no
CR/LF translation, 8 bits), reports the slave's path through ``on_ready`` and keeps
its own slave descriptor open for its whole life, so clients may come and go without
the master ever seeing EIO. The device announces BOOT once, at start; a new client
just sends HELLO. The loop feeds host bytes to the device as they come and advances
virtual time with the ``sim://`` policy (:class:`~tsa_bench.transport.protocol_sim.Pacer`:
at most one quantum per step, never ahead of wall time x speed) - but only once the
previous output has been written to the master, so a client that does not read
stalls the device instead of growing a buffer (natural back-pressure: a silent client
then trips the watchdog, like a real device whose host went away). Returns when
``stop`` is set (checked at least every 50 ms); without ``stop`` it serves forever.
"""

from __future__ import annotations

import errno
import fcntl
import os
import struct
import select
import termios
import threading
import time
import tty
from collections.abc import Callable

from tsa_bench.benchdata import BenchConfig
from tsa_bench.sim.device import SimDevice
from tsa_bench.transport.protocol_sim import Pacer

__all__ = ["serve_pty", "POLL_S", "CHUNK_BYTES"]

#: Longest the loop blocks before looking at ``stop`` again (s).
POLL_S = 0.05
#: Output one device step may produce before it is written out.
CHUNK_BYTES = 1024


def _open_raw_pty() -> tuple[int, int, str]:
    """A pty pair with the slave fully raw (as cfmakeraw): binary-clean both ways."""
    master, slave = os.openpty()
    tty.setraw(slave)
    attrs = termios.tcgetattr(slave)
    attrs[0] &= ~(termios.IGNBRK | termios.BRKINT | termios.PARMRK | termios.ISTRIP | termios.INLCR
                  | termios.IGNCR | termios.ICRNL | termios.IXON | termios.IXOFF)
    attrs[1] &= ~termios.OPOST
    attrs[3] &= ~(termios.ECHO | termios.ECHONL | termios.ICANON | termios.ISIG | termios.IEXTEN)
    termios.tcsetattr(slave, termios.TCSANOW, attrs)
    os.set_blocking(master, False)
    return master, slave, os.ttyname(slave)


def serve_pty(bench: BenchConfig, speed: float | None, seed: int | None,
              on_ready: Callable[[str], None], stop: threading.Event | None = None) -> None:
    """Run a :class:`SimDevice` behind a pty until ``stop`` is set (see module docstring)."""
    master, slave, path = _open_raw_pty()
    try:
        device = SimDevice(bench, seed=seed)
        pacer = Pacer(device, speed)
        device.boot()
        pending = bytearray(device.take_output())
        last_rx = (device.now_s, time.monotonic())
        on_ready(path)
        while stop is None or not stop.is_set():
            if not pending and _unread(slave) == 0 and _host_keeps_up(device, last_rx):
                # Virtual time runs only once the client has read everything sent so
                # far, as sim:// advances only on read: a slow client cannot fall
                # seconds of device time behind and trip the watchdog.
                allowed = pacer.allowed_s()
                if allowed > 0:
                    device.advance(allowed, CHUNK_BYTES)
                    pending += device.take_output()
            if pending:
                timeout = POLL_S
            elif not device.active and device.sampling_period_us == 0:
                timeout = POLL_S      # nothing can happen until the host speaks
            else:
                timeout = min(POLL_S, pacer.wait_s())
            readable, writable, _ = select.select([master], [master] if pending else [], [], timeout)
            if readable:
                data = _read_master(master)
                if data:
                    last_rx = (device.now_s, time.monotonic())
                    device.receive(data)
                    pending += device.take_output()
            if writable and pending:
                written = _write_master(master, pending)
                del pending[:written]
    finally:
        os.close(master)
        os.close(slave)


def _host_keeps_up(device: SimDevice, last_rx: tuple[float, float]) -> bool:
    """Whether virtual time may advance: not more than an eighth of a watchdog period past the
    device time of the host's last frame, unless the host has been silent for two
    watchdog periods of wall time (gone, not slow: then the watchdog must fire).

    Bytes written to the pty reach the client's queue asynchronously, so FIONREAD alone
    can read 0 before the client has seen them; this bounds how far ahead that lets
    the device run.
    """
    last_dev_s, last_wall = last_rx
    watchdog_s = device.limits.watchdog_s
    if time.monotonic() - last_wall > 2 * watchdog_s:
        return True
    return device.now_s < last_dev_s + watchdog_s / 8


def _unread(slave: int) -> int:
    """Bytes written to the client that it has not read yet (FIONREAD on our slave fd)."""
    return struct.unpack("i", fcntl.ioctl(slave, termios.FIONREAD, b"\0\0\0\0"))[0]


def _read_master(master: int) -> bytes:
    try:
        return os.read(master, 4096)
    except BlockingIOError:
        return b""
    except OSError as exc:
        if exc.errno == errno.EIO:   # no slave open anywhere (cannot happen while we hold one)
            return b""
        raise


def _write_master(master: int, data: bytearray) -> int:
    try:
        return os.write(master, data)
    except BlockingIOError:
        return 0
