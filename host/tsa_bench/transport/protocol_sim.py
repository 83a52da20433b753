"""``sim://`` - a pyserial port with a simulated bench device behind it.

Units: virtual (device) time and wall time in s; ``speed`` is virtual s per wall s.

URL: ``sim://[?bench=PATH][&speed=X][&seed=N]`` - every parameter optional: ``bench``
defaults to the shipped configs/bench/sim.yaml, ``speed`` absent or 0 means as fast as
possible, ``seed`` overrides the bench file's plant seed. Bad parameters raise
``ValueError`` naming them. Importing :mod:`tsa_bench.transport` registers the scheme,
so ``serial.serial_for_url("sim://?speed=0", timeout=0.1)`` returns :class:`Serial`.

Contract: ``open()`` builds a fresh :class:`SimDevice` (reachable as ``.device``) and
lets it announce BOOT, like the DTR reset of opening a real Mega. ``write()`` hands the
bytes to the device at once (replies are buffered immediately). ``read(size)`` returns
buffered output; with nothing buffered it advances virtual time by at most one
quantum, ``min(watchdog_s / 8, 0.5)`` s, per call - stopping early at the first
non-SAMPLE frame or ``size`` bytes - so a host that heartbeats every ``watchdog_s / 8``
of device time never trips the watchdog; it may return ``b""`` when the device said
nothing during that quantum (also without a timeout). ``in_waiting`` advances the same
way without ever sleeping. With ``speed`` virtual time never runs ahead of wall time x
speed: ``read`` sleeps (within its timeout) until it may advance. Speed is a cap, not a
clock: virtual time still only advances when the host reads, so a host busy for a
moment (a file flush, a garbage collection) never finds the device seconds ahead with
its watchdog tripped. At full speed no call sleeps: dwells cost no wall time.

In-process fast path: the device keeps its frames decoded (``SimDevice(frames=True)``),
and :meth:`Serial.read_frames` / :meth:`Serial.write_frame` hand them over without
framing, CRC or decoding (:class:`~tsa_bench.device.BenchClient` uses them when the port
has them). Every size and limit above still counts the bytes the frames would take on
the wire, and ``read_frames(size)`` returns exactly the frames whose last byte
``read(size)`` would have returned, so both paths see the same frames at the same
device times; ``read`` and ``write`` keep working on bytes.
"""

from __future__ import annotations

import dataclasses
import math
import time
import urllib.parse
from collections import deque
from dataclasses import dataclass
from pathlib import Path

from serial.serialutil import PortNotOpenError, SerialBase, SerialException, to_bytes

from tsa_bench.bench.config import CONFIG_DIR, load_bench
from tsa_bench.benchdata import BenchConfig
from tsa_bench.userfiles import DocumentError, read_text_file
from tsa_bench.protocol.codec import Frame, MessageDecoder, encode
from tsa_bench.protocol.catalogue import SPEC_BY_CLASS
from tsa_bench.sim.device import SimDevice, frame_bytes

__all__ = ["Serial", "SimUrl", "parse_sim_url", "Pacer", "quantum_s", "hand_over_bench"]

URL_HELP = 'expected "sim://[?bench=PATH][&speed=X][&seed=N]"'
#: Output bytes one ``in_waiting`` poll lets the device produce at most.
POLL_CHUNK_BYTES = 4096
#: Batched delivery: how far past the host's last frame (in watchdog periods) a step may run.
BATCH_WATCHDOG_SHARE = 0.75


@dataclass(frozen=True)
class SimUrl:
    """Parsed ``sim://`` parameters; ``speed`` None = as fast as possible."""

    bench_path: str | None = None
    speed: float | None = None
    seed: int | None = None

    def bench(self) -> BenchConfig:
        """The bench file (validated in full). Its ``port`` and ``simavr.firmware_dir`` are
        not used by the simulated device, so the policies on them do not apply here.
        A bench handed over with :func:`hand_over_bench` for the same file, whose text is
        still what the file holds, is used as it is (it passed the same checks and more)."""
        p = Path(self.bench_path) if self.bench_path is not None else CONFIG_DIR / "sim.yaml"
        known = _HANDED_OVER.get(str(p.resolve()))
        if known is not None:
            try:
                text = read_text_file(p, "bench file")
            except DocumentError:
                text = None   # load_bench says why
            if text == known.source_text:
                return dataclasses.replace(known, path=str(p))
        return load_bench(self.bench_path, allow_url=True, trust_firmware_dir=True)


#: benches this process has loaded and validated in full, by resolved path (hand_over_bench)
_HANDED_OVER: dict[str, BenchConfig] = {}


def hand_over_bench(bench: BenchConfig) -> None:
    """Let a ``sim://`` port opened later on ``bench.path`` use this already validated
    bench instead of loading and checking the file again (it still does when the file's
    text has changed since). ``bench`` must have passed :func:`load_bench`'s checks."""
    if bench.path is not None:
        _HANDED_OVER[str(Path(bench.path).resolve())] = bench


def parse_sim_url(url: str) -> SimUrl:
    """Parse a ``sim://`` URL; raise ValueError naming the bad part."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme.lower() != "sim":
        raise ValueError(f"{URL_HELP}: {url!r} does not start with sim://")
    if parts.netloc or parts.path not in ("", "/") or parts.fragment:
        raise ValueError(f"{URL_HELP}: unexpected {parts.netloc + parts.path + parts.fragment!r} in {url!r}")
    try:
        query = urllib.parse.parse_qs(parts.query, keep_blank_values=True, strict_parsing=bool(parts.query))
    except ValueError as exc:
        raise ValueError(f"{URL_HELP}: malformed query {parts.query!r} ({exc})") from None
    unknown = sorted(set(query) - {"bench", "speed", "seed"})
    if unknown:
        raise ValueError(f"{URL_HELP}: unknown parameter(s) {unknown} in {url!r}")
    values: dict[str, str] = {}
    for key, found in query.items():
        if len(found) != 1:
            raise ValueError(f"{URL_HELP}: parameter '{key}' given {len(found)} times")
        values[key] = found[0]
    bench_path = values.get("bench") or None
    speed: float | None = None
    if "speed" in values:
        try:
            speed = float(values["speed"])
        except ValueError:
            raise ValueError(f"{URL_HELP}: speed={values['speed']!r} is not a number") from None
        if not math.isfinite(speed) or speed < 0:
            raise ValueError(f"{URL_HELP}: speed={values['speed']!r} must be a finite number >= 0")
        speed = speed or None
    seed: int | None = None
    if "seed" in values:
        try:
            seed = int(values["seed"])
        except ValueError:
            raise ValueError(f"{URL_HELP}: seed={values['seed']!r} is not an integer") from None
    return SimUrl(bench_path, speed, seed)


def quantum_s(device: SimDevice) -> float:
    """Most virtual time one read may run: ``min(watchdog_s / 8, 0.5)`` s (the host's heartbeat period)."""
    return min(device.limits.watchdog_s / 8.0, 0.5)


class Pacer:
    """How far a device may run now: one quantum per step, capped at wall time x speed."""

    def __init__(self, device: SimDevice, speed: float | None) -> None:
        self.device = device
        self.speed = speed or None
        self.quantum_s = quantum_s(device)
        self.t0_wall = time.monotonic()

    def allowed_s(self, step_s: float | None = None) -> float:
        """Virtual seconds the device may advance now, at most ``step_s`` (default one
        quantum); <= 0: it must wait."""
        step = self.quantum_s if step_s is None else step_s
        if self.speed is None:
            return step
        ahead = (time.monotonic() - self.t0_wall) * self.speed - self.device.now_s
        return min(step, ahead)

    def wait_s(self) -> float:
        """Wall seconds until the device may advance again (0 when it may now)."""
        if self.speed is None:
            return 0.0
        return max(0.0, (self.device.now_s - (time.monotonic() - self.t0_wall) * self.speed) / self.speed)


class Serial(SerialBase):
    """pyserial port backed by a :class:`SimDevice` (see module docstring)."""

    def __init__(self, *args, **kwargs) -> None:
        self.device: SimDevice | None = None
        self.sim_url: SimUrl | None = None
        self._pacer: Pacer | None = None
        # output not yet read: frames (or raw bytes) with their size on the wire; the
        # first item's first ``_head_read`` bytes were already read
        self._rx: deque[tuple[Frame | bytes, int]] = deque()
        self._rx_bytes = 0
        self._head_read = 0
        self._raw_pending = 0                    # raw-bytes items in _rx
        self._bytes_decoder = MessageDecoder()   # for raw bytes among frames (the boot delimiter)
        self._batching = False
        self.batched_steps = 0                   # device steps run batched (set_batching)
        super().__init__(*args, **kwargs)

    # -- lifecycle --------------------------------------------------------
    def open(self) -> None:
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        self.sim_url = parse_sim_url(self._port)
        self.device = SimDevice(self.sim_url.bench(), seed=self.sim_url.seed, frames=True)
        self._pacer = Pacer(self.device, self.sim_url.speed)
        self.device.boot()
        self._rx.clear()
        self._rx_bytes = self._head_read = self._raw_pending = 0
        self._batching = False
        self._collect()
        self.is_open = True

    def close(self) -> None:
        self.is_open = False

    def from_url(self, url: str) -> SimUrl:
        """Parse (and remember) the URL's parameters without opening."""
        self.sim_url = parse_sim_url(url)
        return self.sim_url

    def _reconfigure_port(self) -> None:
        """Nothing to configure: baud rate and framing do not matter to the simulation."""

    def _update_dtr_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_break_state(self) -> None:
        pass

    # -- bytes ------------------------------------------------------------
    def _check_open(self) -> SimDevice:
        if not self.is_open or self.device is None:
            raise PortNotOpenError()
        return self.device

    def _collect(self) -> None:
        assert self.device is not None
        items = self.device.take_frames()
        if items:
            self._rx.extend(items)
            self._rx_bytes += sum([n for _, n in items])
            self._raw_pending += sum([1 for f, _ in items if type(f) is bytes])

    def _pump(self, max_bytes: int, deadline: float | None) -> None:
        """Advance the device by at most one quantum until it says something.

        ``deadline`` (monotonic) bounds sleeping for the speed cap; None = never sleep.
        """
        dev, pacer = self._check_open(), self._pacer
        assert pacer is not None
        budget = pacer.quantum_s
        if self._batching:   # up to 3/4 of the watchdog past the host's last frame, if that is more
            room = dev.last_host_s + dev.limits.watchdog_s * BATCH_WATCHDOG_SHARE - dev.now_s
            if room > budget:
                budget = room
                dev.batch_segment_events = True
                self.batched_steps += 1
        try:
            while budget > 1e-9 and not self._rx:
                step = min(budget, pacer.allowed_s(budget))
                if step <= 0:
                    remaining = 0.0 if deadline is None else deadline - time.monotonic()
                    if remaining <= 0:
                        return
                    time.sleep(min(remaining, max(pacer.wait_s(), 1e-4)))
                    continue
                budget -= dev.advance(step, max_bytes)
                self._collect()
        finally:
            dev.batch_segment_events = False

    @property
    def device_time_us(self) -> int:
        """The simulated device's clock now (us since boot), for an in-process host."""
        return round(self._check_open().now_s * 1e6)

    def set_batching(self, on: bool) -> None:
        """Batched delivery (in-process hosts only; off after ``open``): while on, the
        device runs up to 3/4 of its watchdog past the host's last frame per step instead
        of one quantum, and does not stop at segment events the host need not act on
        (:meth:`SimDevice.advance`). A host turns it on only while nothing it decides
        depends on when it sees samples or events (an open-loop stretch of its plan
        with the device queue kept fed): then the host sees every frame, in the same
        order, just in fewer reads, and the device's course is the same."""
        self._batching = bool(on)

    @property
    def in_waiting(self) -> int:
        """Buffered bytes; when none, the device first runs (one quantum, never sleeping)."""
        self._check_open()
        if not self._rx:
            self._pump(POLL_CHUNK_BYTES, None)
        return self._rx_bytes - self._head_read

    @property
    def out_waiting(self) -> int:
        self._check_open()
        return 0

    def _wait_for_output(self, size: int) -> None:
        if not self._rx:
            timeout = self._timeout
            if timeout is None:
                deadline: float | None = math.inf
            else:
                deadline = time.monotonic() + timeout if timeout > 0 else None
            self._pump(size, deadline)

    def read(self, size: int = 1) -> bytes:
        self._check_open()
        if size <= 0:
            return b""
        self._wait_for_output(size)
        out = bytearray()
        while self._rx and len(out) < size:
            item, n = self._rx[0]
            data = item if isinstance(item, bytes) else encode(item.message, item.seq)
            take = min(n - self._head_read, size - len(out))
            out += data[self._head_read:self._head_read + take]
            self._consume(take)
        return bytes(out)

    def _consume(self, k: int) -> None:
        """Mark ``k`` more bytes of the first item read (dropping it once wholly read)."""
        self._head_read += k
        if self._head_read == self._rx[0][1]:
            self._rx_bytes -= self._head_read
            self._head_read = 0
            if isinstance(self._rx.popleft()[0], bytes):
                self._raw_pending -= 1

    def read_frames(self, size: int = 1) -> list[Frame]:
        """Like :meth:`read` (same waiting, same ``size`` in wire bytes), but returns the
        frames whose last byte that read would have returned, decoded."""
        self._check_open()
        if size <= 0:
            return []
        self._wait_for_output(size)
        rx = self._rx
        if self._head_read == 0 and self._rx_bytes <= size and not self._raw_pending:
            out = [item for item, _ in rx]    # everything fits: all frames, none in part
            rx.clear()
            self._rx_bytes = 0
            return out
        out: list[Frame] = []
        budget = size
        while self._rx and budget > 0:
            item, n = self._rx[0]
            left = n - self._head_read
            if left > budget:
                self._head_read += budget   # a frame read in part: whole on a later call
                break
            budget -= left
            if isinstance(item, bytes):
                out += self._bytes_decoder.feed(item[self._head_read:])
            else:
                out.append(item)
            self._consume(left)
        return out

    def write(self, data: bytes) -> int:
        dev = self._check_open()
        data = to_bytes(data)
        dev.receive(data)
        self._collect()
        return len(data)

    def write_frame(self, data: bytes, seq: int, message) -> int:
        """Deliver ``message`` (whose frame ``data`` is, with ``seq``; ``data`` may be empty when
        the caller did not encode it) without decoding it; return the frame's size on the wire."""
        dev = self._check_open()
        dev.receive_frame(seq, message)
        self._collect()
        return len(data) or frame_bytes(SPEC_BY_CLASS[type(message)].struct.size)

    def reset_input_buffer(self) -> None:
        dev = self._check_open()
        self._rx.clear()
        self._rx_bytes = self._head_read = self._raw_pending = 0
        self._bytes_decoder = MessageDecoder()
        dev.take_frames()

    def reset_output_buffer(self) -> None:
        self._check_open()

    def cancel_read(self) -> None:
        pass

    def cancel_write(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        self._check_open()
        return True

    @property
    def dsr(self) -> bool:
        self._check_open()
        return True

    @property
    def ri(self) -> bool:
        self._check_open()
        return False

    @property
    def cd(self) -> bool:
        self._check_open()
        return True
