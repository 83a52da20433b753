"""When the runner heartbeats, and when it asks a simulated device for batched delivery.

Units: device time in us (as the device stamps it), wall time in s.

Heartbeat contract (:class:`Pacing`): the runner sends HEARTBEAT once 1/16 of the
device's watchdog has passed since its last frame, in wall time or in device time as
seen in what the device sends (timestamps lag the device clock): the device hears it at
least every eighth of the watchdog, so a line that stalls for less than the rest never
trips it. With the simulated device in the same process (``sim://``: no line to stall)
the device's own clock is read instead, and the heartbeat is due after half the
watchdog, checked before each read (after the commands that feed the queue, which
usually make it unnecessary): a read runs the device at most a quarter of the watchdog
(two quanta), or in a batch up to 3/4 of it past the host's last frame, so the gap the
device sees stays within 3/4 of its watchdog.

Batching contract: batched delivery (``BenchClient.set_batching``; only ``sim://`` has it)
is asked for only while what the runner sends cannot depend on when it sees samples or
events: no settle, track_length or prompt segment among those queued on the device or
within twice the queue of the next segment to send (one refill sends at most one queue's
worth). The device then stops only where the queue needs feeding (protocol/README.md,
"How samples flow on sim://"), and the run it records is the same.
"""

from __future__ import annotations

from collections import deque

from tsa_bench.device import BenchClient
from tsa_bench.plan import Plan, Prompt, Settle, TrackLength
from tsa_bench.protocol import msg

#: Plan actions the runner decides from samples or from when it sees them.
CLOSED_LOOP = (Prompt, Settle, TrackLength)


class Pacing:
    """Heartbeat and batching decisions for one run (see the module contract)."""

    def __init__(self, client: BenchClient, plan: Plan, ident: msg.Identity) -> None:
        self.client = client
        self.heartbeat_wall_s = max(0.05, ident.watchdog_ms / 16000.0)
        #: in process: the device's own clock is known, and heartbeats go before reads
        self.device_clock = client.device_now_us is not None
        self.heartbeat_dev_s = ident.watchdog_ms / 2000.0 if self.device_clock else self.heartbeat_wall_s
        self._segments = plan.segments
        self._margin = 2 * ident.queue_slots + 2
        # closed-loop segments at or after the oldest one not done, among those looked at so far
        # (the runner only moves forward, so the plan is read once, just ahead of the sending)
        self._closed: deque[int] = deque()
        self._looked = 0   # segments before this index have been looked at
        self.allowed = False      # the runner allows batching only between set-up and tear-down
        self._batching = False

    def device_now_us(self, seen_us: int) -> int:
        """The device clock as far as the runner knows it: exactly in process, else the
        latest timestamp seen (``seen_us``)."""
        return self.client.device_now_us if self.device_clock else seen_us  # type: ignore[return-value]

    def heartbeat_due(self, device_now_us: int, last_tx_device_us: int, wall: float) -> bool:
        return ((device_now_us - last_tx_device_us) / 1e6 >= self.heartbeat_dev_s
                or wall - self.client.last_tx_wall >= self.heartbeat_wall_s)

    def update(self, oldest: int, next_to_send: int) -> None:
        """Before a read: batched delivery on or off for where the plan is."""
        if not self.allowed:
            return
        horizon = min(len(self._segments), next_to_send + self._margin + 1)
        i, closed, segments = max(self._looked, oldest), self._closed, self._segments
        while i < horizon:
            if isinstance(segments[i].action, CLOSED_LOOP):
                closed.append(i)
            i += 1
        self._looked = i
        while closed and closed[0] < oldest:
            closed.popleft()
        self.batch(not closed)

    def batch(self, on: bool) -> None:
        if on != self._batching:
            self._batching = on and self.client.set_batching(True)
            if not on:
                self.client.set_batching(False)

    def stop_batching(self) -> None:
        """From now on frame by frame (tear-down, STOP)."""
        self.allowed = False
        self.batch(False)
