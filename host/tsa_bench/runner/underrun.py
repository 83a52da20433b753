"""Which of the device's QUEUE_EMPTY events are underruns.

The runner sends device commands in bursts: one call of its feeding loop sends, one after
another, each acknowledged before the next, until the device's queue is full or the plan
needs a wait (a prompt, a settling or tracking decision). Within a burst the device may
finish a command before the next one reaches it (an instant SET_HEATER at the start of a
run finishes before its ACK is read) and report QUEUE_EMPTY: that is the ACK round trip,
not the host falling behind. Contract of :class:`Bursts`: QUEUE_EMPTY after a command is an
underrun exactly when that command was the last one of its burst (the device then ran dry
waiting for a host that was not there to refill the queue). A command is named by its plan
segment index and its part (1-based: the n-th device command of that segment), as the
device's events name it: QUEUE_EMPTY carries the segment, the SEGMENT_DONE events before it
count the parts.
"""

from __future__ import annotations

from collections import deque


class Bursts:
    """The last command of each burst sent, until the device has gone past it."""

    def __init__(self) -> None:
        self._ends: deque[tuple[int, int]] = deque()
        self._last: tuple[int, int] | None = None   # the last command accepted, (segment, part)
        self._in_burst = False

    def accepted(self, segment: int) -> None:
        """A command of plan segment ``segment`` was queued by the device."""
        last = self._last
        self._last = (segment, last[1] + 1 if last is not None and last[0] == segment else 1)
        self._in_burst = True

    def end(self, oldest: int) -> None:
        """The feeding loop stopped sending (its burst, if it sent anything, ends here);
        ``oldest``: the oldest segment not done (the device's QUEUE_EMPTY after the one
        before it may still come; ends before that are forgotten, so a run that never runs
        dry keeps only a few)."""
        if self._in_burst and self._last is not None:
            self._ends.append(self._last)
        self._in_burst = False
        ends = self._ends
        while ends and ends[0][0] < oldest - 1:
            ends.popleft()

    def ran_dry_after(self, segment: int, part: int) -> bool:
        """QUEUE_EMPTY after ``part`` of ``segment``: True if that command ended a burst."""
        here = (segment, part)
        ends = self._ends
        while ends and ends[0] < here:   # bursts the device finished without running dry
            ends.popleft()
        if ends and ends[0] == here:
            ends.popleft()
            return True
        return False
