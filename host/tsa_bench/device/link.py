"""Link layer for device frames: order them by their header sequence number.

The device numbers every frame it sends (``seq``, u16, wrapping; protocol/README.md).
A serial line can lose, corrupt (the CRC drops it: a loss), duplicate or reorder
frames. Contract of :class:`FrameSequencer`: frames handed to :meth:`push` come out
in sequence order, each at most once:

* a frame whose number comes next is released at once, with any held frames that
  follow it;
* a frame from ahead of a gap is held until the gap fills (a swapped pair is restored),
  until ``depth`` frames are held or the oldest has waited ``hold_s``; then the gap is
  given up as lost and the held frames are released;
* a frame whose number was released recently is a duplicate and is dropped; one from
  behind that was not (a gap given up before, or older than the first frame of the
  session) is late: it is returned apart (:attr:`late`) for the caller to judge (an
  ACK is still useful; a sample is not, it would be out of order);
* a BOOT frame (the device restarted and counts from 0 again) or a number far outside
  the window restarts the count.

Counters in :attr:`stats` say what happened. Nothing here sleeps; :meth:`push` with no
frames releases what has waited long enough.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from tsa_bench.protocol import Frame, msg

SEQ_MOD = 1 << 16
#: Numbers ahead of the expected one that are held as a reordering; farther ahead is a restart.
WINDOW = 1024
#: Numbers remembered as released (for telling duplicates from late frames).
REMEMBER = 4096


@dataclass
class LinkStats:
    """What the sequencer saw: frames ``released`` in order, ``duplicates`` and ``late``
    frames dropped, ``restored`` frames that arrived out of order and were put back,
    ``lost`` frame numbers given up, and ``restarts`` of the count."""

    released: int = 0
    duplicates: int = 0
    late: int = 0
    restored: int = 0
    lost: int = 0
    restarts: int = 0


class FrameSequencer:
    """Releases device frames in sequence order, each once (see the module contract)."""

    def __init__(self, depth: int = 4, hold_s: float = 0.05, clock: Callable[[], float] = time.monotonic) -> None:
        self.depth = depth
        self.hold_s = hold_s
        self.clock = clock
        self.stats = LinkStats()
        self.late: list[Frame] = []
        self.reset()

    def reset(self) -> None:
        """Forget the count (a new session): the next frame sets it."""
        self._expected: int | None = None
        self._held: dict[int, tuple[Frame, float]] = {}
        self._released: set[int] = set()
        # numbers in release order; the last REMEMBER from _order_head on are remembered
        self._released_order: list[int] = []
        self._order_head = 0

    def _ahead(self, seq: int) -> int:
        assert self._expected is not None
        return (seq - self._expected) % SEQ_MOD

    def _release_run(self, out: list[Frame], restored: bool) -> None:
        """Release held frames that now follow on (``restored``: a gap was filled)."""
        while self._expected in self._held:
            frame, _ = self._held.pop(self._expected)
            self.stats.restored += restored
            self._emit(frame, out)

    def _emit(self, frame: Frame, out: list[Frame]) -> None:
        out.append(frame)
        self.stats.released += 1
        self._expected = (frame.seq + 1) % SEQ_MOD
        self._remember(frame.seq)

    def _remember(self, seq: int) -> None:
        self._released.add(seq)
        self._released_order.append(seq)
        self._forget_oldest()

    def _forget_oldest(self) -> None:
        """Forget the numbers beyond the last REMEMBER released (bulk, then compact now and then)."""
        order = self._released_order
        extra = len(order) - self._order_head - REMEMBER
        if extra > 0:
            head = self._order_head
            self._released.difference_update(order[head:head + extra])
            self._order_head = head = head + extra
            if head >= 4 * REMEMBER:
                del order[:head]
                self._order_head = 0

    def _give_up_gap(self, out: list[Frame]) -> None:
        """Declare lost the numbers before the lowest held frame, release from there."""
        lowest = min(self._held, key=self._ahead)
        gap = self._ahead(lowest)
        self.stats.lost += gap
        self._expected = lowest
        self._release_run(out, restored=False)

    def _restart(self, frame: Frame, out: list[Frame]) -> None:
        for seq in sorted(self._held, key=self._ahead):  # what was held is older: release it first
            out.append(self._held[seq][0])
            self.stats.released += 1
        self._held.clear()
        self._released.clear()
        self._released_order.clear()
        self._order_head = 0
        self.stats.restarts += 1
        self._emit(frame, out)

    def push(self, frames: list[Frame]) -> list[Frame]:
        """Frames now in order (possibly none); late ones go to :attr:`late`."""
        out: list[Frame] = []
        if frames and not self._held and self._expected is not None:
            frames = self._release_in_order(frames, out)
        for frame in frames:
            seq = frame.seq
            if self._expected is None:
                self._emit(frame, out)
                continue
            if isinstance(frame.message, msg.Boot):
                self._restart(frame, out)
                continue
            ahead = self._ahead(seq)
            if ahead == 0:
                self._emit(frame, out)
                self._release_run(out, restored=True)
            elif ahead < WINDOW:
                if seq in self._held:
                    self.stats.duplicates += 1
                else:
                    self._held[seq] = (frame, self.clock())
            elif ahead >= SEQ_MOD - SEQ_MOD // 2:  # behind: released already, or late
                if seq in self._released:
                    self.stats.duplicates += 1
                else:
                    self._remember(seq)  # a second copy of it is a duplicate
                    self.stats.late += 1
                    self.late.append(frame)
            else:
                self._restart(frame, out)
            while len(self._held) >= self.depth:
                self._give_up_gap(out)
        now = self.clock()
        while self._held and now - min(t for _, t in self._held.values()) >= self.hold_s:
            self._give_up_gap(out)
        return out

    def _release_in_order(self, frames: list[Frame], out: list[Frame]) -> list[Frame]:
        """The common case in bulk: release the leading frames that follow on, one number
        after another (no gap, no BOOT); return the rest for the general path."""
        expected = self._expected
        n = 0
        for frame in frames:
            if frame.seq != expected or type(frame.message) is msg.Boot:
                break
            expected = (expected + 1) % SEQ_MOD
            n += 1
        if n == 0:
            return frames
        run = frames[:n] if n < len(frames) else frames
        out.extend(run)
        self.stats.released += n
        self._expected = expected
        seqs = [f.seq for f in run]
        self._released.update(seqs)
        self._released_order.extend(seqs)
        self._forget_oldest()
        return frames[n:] if n < len(frames) else []

    def push_consecutive(self, frames: list[Frame]) -> list[Frame]:
        """:meth:`push` for a source that cannot lose, repeat or reorder frames (a device
        in the same process): frames that continue the count one number after another
        (checked at both ends) are released as they are, without remembering each number
        (no duplicate can follow); anything else takes the general path."""
        n = len(frames)
        if not n:
            return frames if not self._held else self.push(frames)
        expected = self._expected
        first, last = frames[0].seq, frames[-1].seq
        if self._held or expected is None or first != expected or (last - first) % SEQ_MOD != n - 1:
            return self.push(frames)
        self._expected = (last + 1) % SEQ_MOD
        self.stats.released += n
        return frames

    def take_late(self) -> list[Frame]:
        """Late frames seen since the last call."""
        late, self.late = self.late, []
        return late
