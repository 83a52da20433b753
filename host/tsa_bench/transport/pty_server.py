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

``as_hardware``: the device passes for the rig (no SIMULATED flag, SIM_SET_LOAD unknown)
and, unless ``reset_on_open`` is False (a Mega wired not to reset), resets whenever a
client opens the port, as a Mega's DTR line does (:meth:`SimDevice.after_reset`: BOOT
external_reset, fault and queue gone, a position known at rest kept). Its load changes
only by what arrives on ``loads`` (g: a person's hand), taken between device steps.
``on_reset`` sees each reset device, ``on_fault`` each change of the latched fault (0: cleared).
"""

from __future__ import annotations

import errno
import fcntl
import math
import os
import queue
import select
import struct
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
#: How long a Mega takes to boot after its DTR reset (s): more line set-up within it is the same open.
BOOT_S = 1.0
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
              on_ready: Callable[[str], None], stop: threading.Event | None = None, *,
              as_hardware: bool = False, reset_on_open: bool = True,
              loads: queue.SimpleQueue[float] | None = None,
              on_reset: Callable[[SimDevice], None] | None = None,
              on_fault: Callable[[int], None] | None = None) -> None:
    """Run a :class:`SimDevice` behind a pty until ``stop`` is set (see module docstring)."""
    master, slave, path = _open_raw_pty()
    opens = OpenWatch(master, slave) if as_hardware and reset_on_open else None
    try:
        device = SimDevice(bench, seed=seed, simulated=not as_hardware)
        pacer = Pacer(device, speed)
        device.boot()
        pending = bytearray(device.take_output())
        last_rx = (device.now_s, time.monotonic())
        on_ready(path)
        latched = 0
        while stop is None or not stop.is_set():
            if on_fault is not None and device.fault != latched:
                latched = device.fault
                on_fault(latched)   # 0: cleared
            while loads is not None and not loads.empty():
                device.set_load_g(loads.get())   # a person hung another load

            if _host_gone(device, last_rx) and (pending or _unread(slave)):
                # nobody reads any more (the client left): what was sent is lost, as on a
                # serial line, and the device runs on (its watchdog must fire)
                termios.tcflush(slave, termios.TCIFLUSH)
                pending.clear()
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
                if opens is not None:
                    opened, data = opens.split(data)
                    if opened:
                        # DTR: the device resets; what it was sending is cut off, BOOT follows
                        device = device.after_reset()
                        pacer = Pacer(device, speed)
                        pending = bytearray(device.take_output())
                        last_rx = (device.now_s, time.monotonic())
                        if on_reset is not None:
                            on_reset(device)
                        continue
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


#: TIOCPKT control bits (linux/tty.h): a termios change on a slave with EXTPROC set, a flush
_TIOCPKT_IOCTL = 0x40
_EXTPROC = 0o200000


class OpenWatch:
    """Tells when a client opens the pty's slave, where a Mega's USB bridge pulses DTR.

    Packet mode on the master and EXTPROC on the slave: a client's open (pyserial sets the
    line's termios) shows on the master as a TIOCPKT_IOCTL control packet. Every read of
    the master then starts with a control byte: 0 before data, else a control packet
    alone (a flush; an open). One open may set the line up more than once: a new open is
    one after the client spoke, or more than :data:`BOOT_S` after the last.
    """

    def __init__(self, master: int, slave: int) -> None:
        attrs = termios.tcgetattr(slave)
        attrs[3] |= _EXTPROC
        termios.tcsetattr(slave, termios.TCSANOW, attrs)
        fcntl.ioctl(master, termios.TIOCPKT, struct.pack("i", 1))
        if select.select([master], [], [], 0)[0]:   # setting EXTPROC above is itself reported once
            os.read(master, 1)
        self._spoke = False
        self._last = -math.inf

    def split(self, packet: bytes) -> tuple[bool, bytes]:
        """(a client opened the port, the data) of one read of the master."""
        if not packet:
            return False, b""
        control, data = packet[0], packet[1:]
        if data:
            self._spoke = True
        if control & _TIOCPKT_IOCTL and (self._spoke or time.monotonic() - self._last > BOOT_S):
            self._spoke, self._last = False, time.monotonic()
            return True, data
        return False, data


def _host_gone(device: SimDevice, last_rx: tuple[float, float]) -> bool:
    """The host has been silent for two watchdog periods of wall time: gone, not slow."""
    return time.monotonic() - last_rx[1] > 2 * device.limits.watchdog_s


def _host_keeps_up(device: SimDevice, last_rx: tuple[float, float]) -> bool:
    """Whether virtual time may advance: not more than an eighth of a watchdog period past the
    device time of the host's last frame, unless the host has been silent for two
    watchdog periods of wall time (gone, not slow: then the watchdog must fire).

    Bytes written to the pty reach the client's queue asynchronously, so FIONREAD alone
    can read 0 before the client has seen them; this bounds how far ahead that lets
    the device run.
    """
    if _host_gone(device, last_rx):
        return True
    return device.now_s < last_rx[0] + device.limits.watchdog_s / 8


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
