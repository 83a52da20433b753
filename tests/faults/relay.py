"""A fault-injecting serial relay for tests: drop, flip, duplicate, swap, delay, stall, cut.

Faults act on whole frames (split at the 0x00 delimiter), independently in each
direction, drawn from a seeded random generator:

* ``drop``: the frame vanishes; ``flip``: one byte of it is XOR-ed with a random
  non-zero value (the CRC must catch it); ``duplicate``: it is sent twice in a row;
  ``swap``: it is held back and sent after the next frame; ``delay`` and ``boundary``
  (towards the host): held back past several frames, anywhere or at segment boundaries
  (:class:`Faults`);
* ``stalls``: ``[(start_s, duration_s), ...]`` on the relay's clock, during which
  nothing passes either way (bytes are kept and delivered when the stall ends);
* ``cut_at_s``: from then on the port fails as an unplugged one does.

Two forms: :class:`FaultyPort` wraps a pyserial-like port in-process (``sim://``, the
native firmware), its clock the simulated device's (virtual time) or the wall clock;
:class:`PtyRelay` sits between a pseudo-terminal the host opens and a device's
pseudo-terminal, in a thread (the host is then any process, e.g. ``tsa-bench run``).
Both keep every frame the device sent, before any fault (``device_frames``), and
every message the host sent, so a test can check what was stored against what was
measured and whether a STOP went out.
"""

from __future__ import annotations

import os
import random
import select
import threading
import time
import tty
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

import serial

from tsa_bench.protocol import MessageDecoder, msg
from tsa_bench.protocol.blocks import expand


@dataclass(frozen=True)
class Faults:
    """Per-frame probabilities (0..1) of each fault in one direction.

    ``delay``: the frame is held back and sent after the next 2..``max_delay_frames``
    frames (beyond the link layer's reordering depth it arrives late). ``boundary``: at
    each EVENT frame of a segment boundary (segment_started, segment_done, queue_empty),
    either that event is held back past the next 1..``max_delay_frames`` frames (samples of
    the next segment overtake it) or the frame just before it (the last sample of the
    segment ending) is held back past it. Only for frames towards the host: a serial line
    never reorders, and a host command overtaken by its successor would defeat the
    device's one-deep repeat filter, which the protocol relies on the line not doing.
    """

    drop: float = 0.0
    flip: float = 0.0
    duplicate: float = 0.0
    swap: float = 0.0
    delay: float = 0.0
    boundary: float = 0.0
    max_delay_frames: int = 6


#: The link campaign of docs/reliability: 1 % drop, 1 % flip, 2 % duplicate, 2 % swap.
CAMPAIGN = Faults(drop=0.01, flip=0.01, duplicate=0.02, swap=0.02)
#: Reordering towards the host: 3 % swapped, 3 % delayed by 2-6 frames, and half of the
#: segment boundaries with the event or the sample before it moved (no loss on the line).
REORDER = Faults(swap=0.03, delay=0.03, boundary=0.5)

_BOUNDARY_EVENTS = {int(msg.EventKind.SEGMENT_STARTED), int(msg.EventKind.SEGMENT_DONE),
                    int(msg.EventKind.QUEUE_EMPTY)}


def _is_boundary(frame: bytes) -> bool:
    """An EVENT frame of a segment boundary (decoded on its own; a damaged frame is not)."""
    found = MessageDecoder().feed(frame)
    return bool(found) and isinstance(found[0].message, msg.Event) and found[0].message.kind in _BOUNDARY_EVENTS


class FrameMangler:
    """Applies :class:`Faults` to a byte stream, frame by frame; ``stats`` counts them."""

    def __init__(self, faults: Faults, rng: random.Random, on_frame: Callable[[bytes], None] | None = None) -> None:
        self.faults, self.rng, self.on_frame = faults, rng, on_frame
        self.stats: Counter[str] = Counter()
        self._partial = bytearray()
        self._held: bytes | None = None      # held for a swap
        self._prev: bytes | None = None      # the last frame, kept back one frame (boundary faults)
        self._delayed: list[list] = []       # [frames still to pass, frame]

    def feed(self, data: bytes) -> bytes:
        out: list[bytes] = []
        self._partial += data
        *frames, rest = bytes(self._partial).split(b"\x00")
        self._partial = bytearray(rest)
        for body in frames:
            if body:
                self._one(body + b"\x00", out)
        return b"".join(out)

    def release_held(self) -> bytes:
        """Every frame held back (swap, delay, boundary), in the order they would have
        gone: the line went quiet, nothing follows them."""
        out: list[bytes] = []
        if self._prev is not None:
            self._emit(self._prev, out)
            self._prev = None
        if self._held is not None:
            self._emit(self._held, out)
            self._held = None
        out += [frame for _, frame in self._delayed]
        self._delayed.clear()
        return b"".join(out)

    def _emit(self, frame: bytes, out: list[bytes]) -> None:
        """Send one frame; frames delayed past it whose count has run out follow it."""
        out.append(frame)
        for d in self._delayed:
            d[0] -= 1
        while self._delayed and self._delayed[0][0] <= 0:
            out.append(self._delayed.pop(0)[1])

    def _delay(self, frame: bytes, lo: int) -> None:
        self._delayed.append([self.rng.randint(lo, max(lo, self.faults.max_delay_frames)), frame])
        self._delayed.sort(key=lambda d: d[0])

    def _one(self, frame: bytes, out: list[bytes]) -> None:
        f, rng = self.faults, self.rng
        if self.on_frame is not None:
            self.on_frame(frame)
        self.stats["frames"] += 1
        if rng.random() < f.drop:
            self.stats["dropped"] += 1
            return
        if rng.random() < f.flip and len(frame) > 1:
            b = bytearray(frame)
            i = rng.randrange(len(b) - 1)
            b[i] ^= rng.randrange(1, 256)
            frame = bytes(b)
            self.stats["flipped"] += 1
        if f.boundary:
            prev, self._prev = self._prev, frame
            if _is_boundary(frame) and rng.random() < f.boundary:
                if prev is not None and rng.random() < 0.5:
                    self.stats["boundary_before"] += 1    # the frame before the event goes after it
                    self._delay(prev, 1)
                    prev = None
                else:
                    self.stats["boundary_event"] += 1     # the event goes after what follows it
                    self._prev = None
                    self._delay(frame, 1)
            if prev is None:
                return
            frame = prev
        self._pass(frame, out)

    def _pass(self, frame: bytes, out: list[bytes]) -> None:
        f, rng = self.faults, self.rng
        if self._held is not None:
            held, self._held = self._held, None
            self._emit(frame, out)
            self._emit(held, out)
            self.stats["swapped"] += 1
            return
        if rng.random() < f.swap:
            self._held = frame
            return
        if rng.random() < f.delay:
            self.stats["delayed"] += 1
            self._delay(frame, 2)
            return
        self._emit(frame, out)
        if rng.random() < f.duplicate:
            self._emit(frame, out)
            self.stats["duplicated"] += 1


class _Recorder:
    """Decodes the frames one side sent (before faults) and keeps them."""

    def __init__(self) -> None:
        self._decoder = MessageDecoder()
        self.messages: list = []

    def __call__(self, frame: bytes) -> None:
        self.messages += [f.message for f in self._decoder.feed(frame)]

    def samples(self) -> dict[int, msg.Sample]:
        """Every sample sent, by counter (SAMPLE_BLOCKs expanded)."""
        return {m.counter: m for m in expand(self.messages) if isinstance(m, msg.Sample)}

    def count(self, kind: type) -> int:
        return sum(isinstance(m, kind) for m in self.messages)


@dataclass
class LinkFaults:
    """Faults of a whole link: per direction, stalls and a cut (see the module docstring)."""

    to_host: Faults = field(default_factory=Faults)
    to_device: Faults = field(default_factory=Faults)
    stalls: tuple[tuple[float, float], ...] = ()
    cut_at_s: float | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        if self.to_device.delay or self.to_device.boundary:
            raise ValueError("delay and boundary faults are for frames towards the host (see Faults)")


class _Link:
    """State shared by both relay forms."""

    def __init__(self, faults: LinkFaults, clock: Callable[[], float]) -> None:
        rng = random.Random(faults.seed)
        self.faults, self.clock = faults, clock
        self.device_frames = _Recorder()
        self.host_frames = _Recorder()
        self.up = FrameMangler(faults.to_host, random.Random(rng.getrandbits(64)), self.device_frames)
        self.down = FrameMangler(faults.to_device, random.Random(rng.getrandbits(64)), self.host_frames)
        self._t0 = clock()
        self.stalled_s = 0.0

    def now_s(self) -> float:
        return self.clock() - self._t0

    def stalled(self) -> bool:
        t = self.now_s()
        return any(a <= t < a + d for a, d in self.faults.stalls)

    def cut(self) -> bool:
        return self.faults.cut_at_s is not None and self.now_s() >= self.faults.cut_at_s

    @property
    def stats(self) -> dict[str, Counter[str]]:
        return {"to_host": self.up.stats, "to_device": self.down.stats}


class FaultyPort:
    """A pyserial-like port with faults between the host and ``port`` (module docstring).

    ``clock`` defaults to the simulated device's clock when ``port`` is ``sim://`` (the
    device then keeps running, in virtual time, through a stall), else the wall clock.
    """

    def __init__(self, port, faults: LinkFaults, clock: Callable[[], float] | None = None) -> None:
        self._port = port
        if clock is None:
            device = getattr(port, "device", None)
            clock = (lambda: device.now_s) if device is not None else time.monotonic
        self.link = _Link(faults, clock)
        self._rx = bytearray()       # passed the faults, for the host
        self._to_device = bytearray()  # held during a stall
        self.port = getattr(port, "port", "faulty")
        self.baudrate = getattr(port, "baudrate", 250000)
        self.timeout = getattr(port, "timeout", 0.05)

    def __getattr__(self, name):
        return getattr(self._port, name)

    def _check(self) -> None:
        if self.link.cut():
            raise serial.SerialException("device disconnected (relay cut the line)")

    def _pull(self, size: int) -> None:
        data = self._port.read(size)
        if self.link.stalled():
            self.link.up._partial += data  # kept; delivered once the stall ends
            return
        if self._to_device:
            self._port.write(self.link.down.feed(bytes(self._to_device)))
            self._to_device.clear()
        out = self.link.up.feed(data)
        if not out and not data:
            out = self.link.up.release_held()
        self._rx += out
        held = self.link.down.release_held()  # a swapped host frame is not held for ever either
        if held:
            self._port.write(held)

    @property
    def in_waiting(self) -> int:
        self._check()
        if not self._rx:
            self._pull(4096)
        return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        self._check()
        if not self._rx:
            self._pull(max(size, 1))
        data = bytes(self._rx[:size])
        del self._rx[:size]
        return data

    def write(self, data: bytes) -> int:
        self._check()
        if self.link.stalled():
            self._to_device += data
        else:
            self._port.write(self.link.down.feed(bytes(self._to_device) + data))
            self._to_device.clear()
        return len(data)

    def reset_input_buffer(self) -> None:
        self._rx.clear()
        self._port.reset_input_buffer()

    def close(self) -> None:
        self._port.close()


class PtyRelay:
    """Relays between a new pseudo-terminal (:attr:`path`, for the host) and the device
    pseudo-terminal ``device_path``, with faults, in a thread, until :meth:`close`."""

    def __init__(self, device_path: str, faults: LinkFaults) -> None:
        self.link = _Link(faults, time.monotonic)
        self._master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self._slave = slave                       # kept open: the host may come and go
        self._device = os.open(device_path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self._device)
        for fd in (self._master, self._device):
            os.set_blocking(fd, False)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        to_host, to_device = bytearray(), bytearray()
        idle_since = time.monotonic()
        while not self._stop.is_set():
            readable, _, _ = select.select([self._master, self._device], [], [], 0.005)
            now = time.monotonic()
            for fd in readable:
                try:
                    data = os.read(fd, 4096)
                except (BlockingIOError, OSError):
                    continue
                (to_device if fd == self._master else to_host).extend(data)
            if self.link.stalled() or self.link.cut():
                continue  # bytes wait; after a cut they never pass
            if to_device:
                self._write(self._device, self.link.down.feed(bytes(to_device)))
                to_device.clear()
            if to_host:
                self._write(self._master, self.link.up.feed(bytes(to_host)))
                to_host.clear()
                idle_since = now
            elif now - idle_since > 0.02:
                self._write(self._master, self.link.up.release_held())
                idle_since = now

    @staticmethod
    def _write(fd: int, data: bytes) -> None:
        while data:
            try:
                n = os.write(fd, data)
                data = data[n:]
            except BlockingIOError:
                select.select([], [fd], [], 0.05)
            except OSError:
                return

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        for fd in (self._master, self._slave, self._device):
            try:
                os.close(fd)
            except OSError:
                pass
