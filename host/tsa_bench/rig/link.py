"""An open bench device for the rig commands: connect, read, move, heat, stop.

Units: twist in turns, rates in turns/s and turns/s^2, voltage in V, time in s of
device time (``t_us`` on the wire) unless a name says ``wall``.

Contract: :func:`open_link` opens the port (serial device, ``sim://`` or any URL the
port policy let through), waits for the boot announcement and completes the handshake
(a device speaking another catalogue raises :class:`RigError` with the client's
explanation). Everything here goes through :class:`~tsa_bench.device.BenchClient`:
device commands outside any plan carry the segment ``NO_SEGMENT``. The link keeps the
device's watchdog fed whenever it waits (:meth:`RigLink.pump`), converts what arrives
with the bench calibration, and on :meth:`RigLink.close` sends STOP (motor halted,
heater off) and turns sampling off, so a rig command that ends for any reason leaves
the rig at rest.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import NamedTuple

from tsa_bench.benchdata import BenchConfig
from tsa_bench.device import BenchClient, DeviceError
from tsa_bench.device.faults import CLEARS, RECOVERY, fault_name, latched_text
from tsa_bench.protocol import msg
from tsa_bench.runner.commands import NO_SEGMENT


class RigError(RuntimeError):
    """A rig command cannot go on; the message says what happened and what to check."""


@dataclass
class RigLink:
    """A connected device (see the module contract)."""

    client: BenchClient
    bench: BenchConfig
    port_name: str
    on_message: Callable[[NamedTuple], None] | None = None   # sees every message read
    t0_us: int | None = None
    now_us: int = 0
    fault: int = 0
    last_status: msg.QueueStatus | None = None
    cleared: msg.QueueStatus | None = None   # the status that showed a fault :meth:`clear_fault` cleared
    _last_beat_wall: float = field(default_factory=time.monotonic)
    _last_beat_us: int = 0

    @property
    def identity(self) -> msg.Identity:
        assert self.client.identity is not None
        return self.client.identity

    @property
    def simulated(self) -> bool:
        return bool(self.identity.flags & msg.DeviceFlags.SIMULATED)

    @property
    def steps_per_turn(self) -> int:
        return self.identity.steps_per_turn

    def t_s(self, t_us: int) -> float:
        """Device time (s) since this link began."""
        return (t_us - (self.t0_us or 0)) / 1e6

    # -- messages ------------------------------------------------------------
    def _seen(self, m: NamedTuple) -> None:
        t_us = getattr(m, "t_us", None)
        if t_us is not None:
            if self.t0_us is None:
                self.t0_us = t_us
            self.now_us = max(self.now_us, t_us)
        if isinstance(m, msg.QueueStatus):
            self.last_status = m
            self.fault = m.fault
        elif isinstance(m, msg.Event) and m.kind == msg.EventKind.FAULT:
            self.fault = m.code
        if self.on_message is not None:
            self.on_message(m)

    def pump(self) -> list[NamedTuple]:
        """Read what arrived (handing each message to ``on_message``) and heartbeat."""
        got = self.client.poll()
        for m in got:
            self._seen(m)
        # every 1/16 watchdog of wall or device time (a simulation runs ahead of the wall clock)
        beat_s = max(0.05, self.identity.watchdog_ms / 16000.0)
        if (time.monotonic() - max(self._last_beat_wall, self.client.last_tx_wall) >= beat_s
                or (self._device_now_us() - self._last_beat_us) / 1e6 >= beat_s):
            self.heartbeat()
        return got

    def _device_now_us(self) -> int:
        """The device's clock: read from an in-process simulation (which says nothing while
        a move runs with sampling off), else the latest time the device reported."""
        now = self.client.device_now_us
        return self.now_us if now is None else now

    def heartbeat(self) -> None:
        self.client.command(msg.Heartbeat(), check=False)
        self._last_beat_wall = time.monotonic()
        self._last_beat_us = self._device_now_us()

    def status(self) -> msg.QueueStatus:
        """A fresh QUEUE_STATUS (HEARTBEAT and its answer)."""
        self.last_status = None
        self.heartbeat()
        deadline = time.monotonic() + 2.0 + 2 * self.client.ack_timeout_s
        while self.last_status is None:
            self.pump()
            if time.monotonic() > deadline:
                raise RigError(f"the device on {self.port_name} did not report its status")
        return self.last_status

    def clear_fault(self, say: Callable[[str], None]) -> msg.QueueStatus | None:
        """A fault latched before this command: ``say`` what it is, then CLEAR_QUEUE.
        Returns the status that showed it (None: no fault was latched); RigError when
        the fault stays (its cause is still there)."""
        status = self.status()
        if not status.fault:
            return None
        say(f"{latched_text(status, self.identity)}. Clearing it now (CLEAR_QUEUE).")
        self.cleared = status
        self.client.command(msg.ClearQueue(), check=False)
        after = self.status()
        if after.fault:
            raise RigError(f"the device keeps fault {fault_name(after.fault)} latched after CLEAR_QUEUE: its "
                           f"cause is still there; {RECOVERY.get(fault_name(after.fault), '')}")
        return status

    def position_known(self) -> bool:
        """Whether the device knows the motor's step position (no ``position_unknown`` bit)."""
        return not self.status().state & msg.DeviceState.POSITION_UNKNOWN

    def require_position(self) -> str | None:
        """Make sure moves will be accepted: the device must know its position.

        A simulated device that does not know it is told 0 (its plant starts untwisted),
        and the returned note says so; a real one raises :class:`RigError` pointing to
        ``tsa-bench zero``. Returns None when the position was already known."""
        if self.position_known():
            return None
        if not self.simulated:
            raise RigError("the device does not know the motor's position (it powered up, reset while moving, or "
                           "released the motor): hang the TSA untwisted and run `tsa-bench zero` (or "
                           "`tsa-bench zero --turns N` when you know its twist), then try again; nothing moved")
        self.set_position(0.0)
        return "the simulated device did not know its position: its untwisted start is the twist zero"

    def set_position(self, turns: float) -> int:
        """SET_POSITION: declare the motor is at ``turns`` now. Returns the steps sent;
        RigError when the device refuses (a move running, or beyond its twist limits)."""
        steps = round(turns * self.steps_per_turn)
        ack = self.client.command(msg.SetPosition(steps), check=False)
        if ack.status != msg.Status.OK:
            raise RigError(f"the device refused to set its position to {turns:g} turns: "
                           f"{msg.Status(ack.status).name.lower()}")
        for m in self.client.poll():
            self._seen(m)
        return steps

    # -- commands ------------------------------------------------------------
    def queued(self, message: NamedTuple, what: str) -> None:
        """One queued command (segment NO_SEGMENT); RigError when the device refuses it."""
        ack = self.client.command(message, check=False)
        while ack.status == msg.Status.QUEUE_FULL:
            self.pump()
            ack = self.client.command(message, check=False)
        if ack.status != msg.Status.OK:
            reason = msg.Status(ack.status).name.lower()
            hint = ""
            if ack.status == msg.Status.BAD_STATE and self.fault:
                hint = f" (device fault {fault_name(self.fault)} latched; {CLEARS})"
            elif ack.status == msg.Status.BAD_STATE:
                hint = " (the device does not know its position yet: tsa-bench zero)"
            raise RigError(f"the device refused {what}: {reason}{hint}")
        for m in self.client.poll():  # what the device said before this command: not about it
            self._seen(m)

    def set_sampling(self, period_s: float, segment: int = NO_SEGMENT) -> None:
        self.queued(msg.SetSampling(segment, round(period_s * 1e6)), "the sampling period")

    def set_heater(self, voltage_V: float, segment: int = NO_SEGMENT) -> None:
        self.queued(msg.SetHeater(segment, round(voltage_V * 1000)), f"heater {voltage_V:g} V")

    def move_to(self, turns: float, rate_turns_per_s: float, accel_turns_per_s2: float,
                segment: int = NO_SEGMENT) -> None:
        spt = self.steps_per_turn
        self.queued(msg.MoveTo(segment, round(turns * spt), max(1, round(rate_turns_per_s * spt)),
                               max(1, round(accel_turns_per_s2 * spt))), f"the move to {turns:g} turns")

    def wait_idle(self, timeout_s: float, should_stop: Callable[[], bool] | None = None) -> bool:
        """Wait until the device has run everything queued; False if ``should_stop`` said
        so first (the caller then STOPs). RigError on a fault or a timeout (wall time)."""
        deadline = time.monotonic() + timeout_s
        self.heartbeat()
        while True:
            for m in self.pump():
                if isinstance(m, msg.QueueStatus) and not m.executing and m.queue_free == self.identity.queue_slots:
                    return True
                if isinstance(m, msg.Event) and m.kind == msg.EventKind.QUEUE_EMPTY:
                    return True
            if self.fault:
                raise RigError(f"device fault {fault_name(self.fault)}: {RECOVERY.get(fault_name(self.fault), '')}; "
                               f"{CLEARS}")
            if should_stop is not None and should_stop():
                return False
            if time.monotonic() > deadline:
                raise RigError(f"the device on {self.port_name} did not finish within {timeout_s:g} s")

    def samples(self, duration_s: float, on_sample: Callable[[msg.Sample], None] | None = None) -> list[msg.Sample]:
        """The SAMPLEs of the next ``duration_s`` of device time (sampling must be on)."""
        out: list[msg.Sample] = []
        start: int | None = None
        wall_deadline = time.monotonic() + duration_s * 3 + 5.0
        while True:
            for m in self.pump():
                if isinstance(m, msg.Sample):
                    start = m.t_us if start is None else start
                    out.append(m)
                    if on_sample is not None:
                        on_sample(m)
                    if (m.t_us - start) / 1e6 >= duration_s:
                        return out
            if self.fault:
                raise RigError(f"device fault {fault_name(self.fault)}: {RECOVERY.get(fault_name(self.fault), '')}; "
                               f"{CLEARS}")
            if time.monotonic() > wall_deadline:
                raise RigError(f"no samples from the device on {self.port_name} for {duration_s * 3 + 5:g} s")

    def stop(self) -> None:
        """STOP: motor halted, heater off, queue cleared (best effort, never raises)."""
        self.client.stop()

    def close(self) -> None:
        """Leave the rig at rest: STOP, sampling off, the reset of the next open armed so the
        position survives it (best effort: refused while the motor still decelerates)."""
        try:
            self.stop()
            self.client.command(msg.SetSampling(NO_SEGMENT, 0), check=False)
            self.client.arm_reset()
        except DeviceError:
            pass


@contextmanager
def open_link(port: str, bench: BenchConfig, *, boot_timeout_s: float | None = None) -> Iterator[RigLink]:
    """Open ``port``, handshake, yield a :class:`RigLink`; STOP and close at the end."""
    import serial

    from tsa_bench import transport  # noqa: F401  (registers sim://)

    try:
        ser = serial.serial_for_url(port, baudrate=bench.baud, timeout=0.05, write_timeout=2.0)
    except (serial.SerialException, ValueError, OSError) as exc:
        raise RigError(f"cannot open {port}: {exc}; check the device is plugged in, the port name "
                       "(tsa-bench ports) and that no other program holds it") from None
    try:
        client = BenchClient(ser, ack_timeout_s=bench.ack_timeout_s, watchdog_s=bench.watchdog_s)
        try:
            client.connect(bench.boot_timeout_s if boot_timeout_s is None else boot_timeout_s, baud=bench.baud)
        except DeviceError as exc:
            raise RigError(str(exc)) from None
        link = RigLink(client, bench, port)
        try:
            link.status()
            yield link
        finally:
            link.close()
    finally:
        ser.close()
