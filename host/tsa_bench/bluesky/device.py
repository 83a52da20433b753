"""A TSA rig as an ophyd-async device: twist and heater to move, length and resistance to read.

Units: ``twist`` in turns (readback and setpoint; ``velocity`` turn/s, ``acceleration``
turn/s^2), ``heater`` in V, ``length`` in mm, ``resistance`` in ohm, ``step_position``
in steps, ``device_time`` in s of device time since the rig connected, ``load`` in g of
hanging mass, ``sampling_period`` and ``integration_time`` in s. Every descriptor says
its units and precision; the movables' readbacks also carry their limits.

Contract of :class:`TsaRig` (one rig on one port: a serial device, ``sim://``, a
``tsa-bench sim-serve`` or native-firmware pty), all of it through
:class:`~tsa_bench.bluesky.session.RigSession`, i.e. the device client the runner uses:

* ``connect`` opens the port and handshakes (``init_devices()`` does it).
* ``stage`` (the rig, or any of its measured signals: the rig counts them) makes sure
  the device knows its twist zero - a simulated device is told 0, a real one that does
  not know it makes ``stage`` fail with :class:`~tsa_bench.bluesky.session.PositionUnknown`
  saying how to declare it (:meth:`TsaRig.declare_twist`); nothing asks on a terminal -
  and switches sampling on every ``sampling_period``. The last ``unstage`` sends STOP
  (motor halted, heater off) and switches sampling off: a plan never leaves the heater on.
* ``twist.set(turns)`` queues one move at ``velocity`` and ``acceleration`` and completes
  when the device reports the move done; a target, rate or acceleration outside the
  bench's limits (or the device's) fails before anything is sent, and the device checks
  its own limits again. ``heater.set(volts)`` likewise (bench heater limit; the device's
  duty limit and its sense-current interlock hold). ``stop()`` on either, which the
  RunEngine calls on abort, pause and stop (and at every plan's end), sends STOP:
  the motor halts, the heater goes off, and a move under way fails.
* Reading ``length``, ``resistance``, ``step_position`` or ``device_time`` takes an
  acquisition: the samples of ``integration_time`` s of device time (a DWELL), reduced
  (:class:`~tsa_bench.bluesky.session.Acquisition`). The signals read in one event share
  it: a signal read a second time, a move, a heater change or a new load starts a new
  one. So ``count([rig.length], 10)`` gives ten acquisitions, and ``scan([rig.length,
  rig.resistance], rig.twist, ...)`` one per point, with length and resistance from the
  same samples. Each reading's timestamp is the acquisition's (:meth:`TsaRig.acquisition_at`).
"""

from __future__ import annotations

import asyncio
import math
import urllib.parse
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

from ophyd_async.core import (
    AsyncStatus, DeviceConnector, MovableLogic, SignalRW, StandardMovable, StandardReadable,
    StandardReadableFormat as Format, TimeoutCalculator,
)

from tsa_bench.bench import load_bench
from tsa_bench.bench.ports import check_port
from tsa_bench.benchdata import BenchConfig
from tsa_bench.bluesky.session import (
    DEFAULT_PERIOD_S, DEFAULT_WINDOW_S, Acquisition, RigRefused, RigSession, RigStopped,
)
from tsa_bench.bluesky.signals import RigBackend, SampledSignal, now, rig_signal
from tsa_bench.protocol import msg
from tsa_bench.shipped import find_config, shipped

#: Acquisitions kept for :meth:`TsaRig.acquisition_at` (the documents bridge looks them up).
KEEP_ACQUISITIONS = 100_000


def _bench_for(port: str, bench: str | Path | BenchConfig | None, allow_url: bool) -> BenchConfig:
    if isinstance(bench, BenchConfig):
        return bench
    if bench is None:
        default = "sim.yaml" if port.lower().startswith("sim://") else "arduino-mega.yaml"
        return load_bench(shipped(f"bench/{default}"), allow_url=allow_url)
    return load_bench(find_config(bench, "bench")[0], allow_url=allow_url)


def _sim_url_with_bench(port: str, bench: BenchConfig) -> str:
    """A ``sim://`` URL without ``bench=`` simulates the bench file the rig was given."""
    if not port.lower().startswith("sim://") or not bench.path:
        return port
    query = urllib.parse.parse_qs(urllib.parse.urlsplit(port).query)
    if "bench" in query:
        return port
    sep = "&" if "?" in port else "?"
    return f"{port}{sep}{urllib.parse.urlencode({'bench': str(Path(bench.path).resolve())})}"


def _config_rw(datatype: type, initial: Any, *, port: str, quantity: str, units: str, precision: int,
               setter: Callable) -> SignalRW:
    return SignalRW(RigBackend(datatype, initial, port=port, quantity=quantity, units=units,
                               precision=precision, setter=setter), timeout=None)


class _RigConnector(DeviceConnector):
    """Opens the rig's session before its signals connect."""

    async def connect_real(self, device: Any, timeout: float, force_reconnect: bool) -> None:
        await device._open()
        await super().connect_real(device, timeout, force_reconnect)


@dataclass
class _AxisLogic(MovableLogic[float]):
    """How the twist and the heater move: one session job each, STOP to stop."""

    rig: "TsaRig"
    check: Callable[[float], Any]
    go: Callable[[float], Any]
    stopping: bool = False

    async def check_move(self, new_position: float) -> None:
        self.rig._require_idle()
        await self.check(new_position)

    async def get_units_precision(self) -> tuple[str | None, int | None]:
        meta = self.readback._connector.backend.metadata
        return meta.get("units"), meta.get("precision")

    async def move(self, new_position: float, timeout: TimeoutCalculator) -> None:
        await self.setpoint.set(new_position)
        self.rig._invalidate()
        self.stopping = False
        try:
            await self.go(new_position)
        except RigStopped:
            if self.stopping:   # this axis's stop(): the move ends as StandardMovable's stop asked
                raise asyncio.CancelledError from None
            raise               # stopped through the rig or the other axis: a failed move, said so

    async def stop(self) -> None:
        self.stopping = True
        await self.rig._send_stop()


class TwistAxis(StandardReadable, StandardMovable[float]):
    """The motor's twist (turns): ``set`` moves and waits for the device to finish."""

    def __init__(self, rig: "TsaRig", name: str = "") -> None:
        port = rig.port
        object.__setattr__(self, "_rig", rig)   # a reference, not a child device
        with self.add_children_as_readables(Format.HINTED_UNCACHED_SIGNAL):
            self.readback = rig_signal(float, 0.0, port=port, quantity="turns", units="turn", precision=4,
                                       getter=rig._twist_now)
        with self.add_children_as_readables(Format.CONFIG_SIGNAL):
            self.velocity = _config_rw(float, 1.0, port=port, quantity="velocity", units="turn/s", precision=3,
                                       setter=None)
            self.acceleration = _config_rw(float, 10.0, port=port, quantity="acceleration", units="turn/s^2",
                                           precision=3, setter=None)
        self.setpoint = _config_rw(float, 0.0, port=port, quantity="turns_setpoint", units="turn", precision=4,
                                   setter=None)
        super().__init__(name=name)

    @cached_property
    def movable_logic(self) -> _AxisLogic:
        rig = self._rig

        async def check(turns: float) -> None:
            rate, accel = await self.velocity.get_value(), await self.acceleration.get_value()
            rig.session.check_twist(turns, rate, accel)

        async def go(turns: float) -> None:
            rate, accel = await self.velocity.get_value(), await self.acceleration.get_value()
            await rig._job(rig.session.move, turns, rate, accel)

        return _AxisLogic(setpoint=self.setpoint, readback=self.readback, rig=rig, check=check, go=go)


class HeaterAxis(StandardReadable, StandardMovable[float]):
    """The heater (V, equivalent DC): ``set`` switches it and waits until it is applied."""

    def __init__(self, rig: "TsaRig", name: str = "") -> None:
        port = rig.port
        object.__setattr__(self, "_rig", rig)   # a reference, not a child device
        with self.add_children_as_readables(Format.HINTED_UNCACHED_SIGNAL):
            self.readback = rig_signal(float, 0.0, port=port, quantity="heater_voltage", units="V", precision=3,
                                       getter=rig._heater_now)
        self.setpoint = _config_rw(float, 0.0, port=port, quantity="heater_setpoint", units="V", precision=3,
                                   setter=None)
        super().__init__(name=name)

    @cached_property
    def movable_logic(self) -> _AxisLogic:
        rig = self._rig

        async def check(volts: float) -> None:
            rig.session.check_heater(volts)

        async def go(volts: float) -> None:
            await rig._job(rig.session.heat, volts)

        return _AxisLogic(setpoint=self.setpoint, readback=self.readback, rig=rig, check=check, go=go)


class TsaRig(StandardReadable):
    """One TSA rig (see the module contract).

    ``port``: ``"sim://"`` (optionally ``?seed=N&speed=X``), a serial device path, or the
    pty of ``tsa-bench sim-serve`` / the native firmware. ``bench``: a bench file (path,
    shipped name or :class:`BenchConfig`); default the simulated bench for ``sim://``,
    the Arduino Mega bench for a serial port. ``sampling_period_s`` and
    ``integration_time_s`` are the starting values of those configuration signals."""

    def __init__(self, port: str = "sim://", bench: str | Path | BenchConfig | None = None, *, name: str = "",
                 sampling_period_s: float = DEFAULT_PERIOD_S, integration_time_s: float = DEFAULT_WINDOW_S,
                 allow_url: bool = False, boot_timeout_s: float | None = None) -> None:
        check_port(port, allow_url=allow_url)
        if not (0 < sampling_period_s < integration_time_s):
            raise ValueError(f"sampling_period_s ({sampling_period_s!r}) must be > 0 and shorter than "
                             f"integration_time_s ({integration_time_s!r}), so every acquisition holds a sample")
        self.bench = _bench_for(port, bench, allow_url)
        self.port = port   # as given: the signals' sources name it
        self.session = RigSession(_sim_url_with_bench(port, self.bench), self.bench, boot_timeout_s=boot_timeout_s,
                                  label=port)
        self._staged = 0
        self._flying = False
        self._lock: asyncio.Lock | None = None
        self._current: Acquisition | None = None
        self._reported: set[str] = set()
        self._by_time: dict[float, Acquisition] = {}
        self._order: deque[float] = deque()
        port = self.port
        with self.add_children_as_readables(Format.HINTED_UNCACHED_SIGNAL):
            self.length = self._sampled("length", "mm", 4, lambda a: a.length_mm)
            self.resistance = self._sampled("resistance", "ohm", 5, lambda a: a.resistance_ohm)
        with self.add_children_as_readables(Format.UNCACHED_SIGNAL):
            self.step_position = self._sampled("step_position", "step", None, lambda a: a.step_position, int, 0)
            self.device_time = self._sampled("device_time", "s", 6, lambda a: a.t_s)
        with self.add_children_as_readables(Format.CHILD):
            self.twist = TwistAxis(self)
            self.heater = HeaterAxis(self)
        with self.add_children_as_readables(Format.CONFIG_SIGNAL):
            self.load = _config_rw(float, math.nan, port=port, quantity="load", units="g", precision=1,
                                   setter=self._set_load)
            self.sampling_period = _config_rw(float, sampling_period_s, port=port, quantity="sampling_period",
                                              units="s", precision=6, setter=self._set_period)
            self.integration_time = _config_rw(float, integration_time_s, port=port, quantity="integration_time",
                                               units="s", precision=6, setter=self._set_window)
        self._period_s, self._window_s = sampling_period_s, integration_time_s
        super().__init__(name=name, connector=_RigConnector())

    def _sampled(self, quantity: str, units: str, precision: int | None, pick: Callable[[Acquisition], Any],
                 datatype: type = float, initial: Any = math.nan) -> SampledSignal:
        async def getter() -> tuple[Any, float]:
            acq = await self.acquisition(quantity)
            return pick(acq), acq.wall_time

        backend = RigBackend(datatype, initial, port=self.port, quantity=quantity, units=units, precision=precision,
                             getter=getter)
        return SampledSignal(backend, self._stage_rig, self._unstage_rig)

    # -- the session -----------------------------------------------------------
    async def _job(self, fn: Callable[..., Any], *args: Any) -> Any:
        return await asyncio.wrap_future(self.session.submit(fn, *args))

    async def _open(self) -> None:
        if self.session.link is not None:
            return
        ident: msg.Identity = await self._job(self.session.open)
        spt, lim = ident.steps_per_turn, self.bench.limits
        lo = max(ident.min_twist_steps / spt, lim.min_twist_turns if lim.min_twist_turns is not None else -math.inf)
        hi = min(ident.max_twist_steps / spt, lim.max_twist_turns if lim.max_twist_turns is not None else math.inf)
        self.twist.readback._connector.backend.set_limits(lo, hi)
        self.twist.setpoint._connector.backend.set_limits(lo, hi)
        top_rate = min(ident.max_rate_steps_per_s / spt, lim.max_rate_turns_per_s or math.inf)
        top_accel = min(ident.max_accel_steps_per_s2 / spt, lim.max_accel_turns_per_s2 or math.inf)
        self.twist.velocity._connector.backend.set_limits(0.0, top_rate)
        self.twist.acceleration._connector.backend.set_limits(0.0, top_accel)
        for sig in (self.heater.readback, self.heater.setpoint):
            sig._connector.backend.set_limits(0.0, lim.max_heater_voltage_V)

    async def _send_stop(self) -> None:
        if self.session.link is not None:
            await asyncio.wrap_future(self.session.request_stop())

    def _require_idle(self) -> None:
        if self._flying:
            raise RigRefused("a protocol is running on the rig: wait for it to complete (or stop it) before "
                             "moving the twist or switching the heater")

    def _invalidate(self) -> None:
        self._current = None

    async def _twist_now(self) -> tuple[float, float]:
        link = self.session.link
        spt = link.steps_per_turn if link is not None else self.bench.steps_per_turn
        return self.session.position_steps / spt, now()

    async def _heater_now(self) -> tuple[float, float]:
        return self.session.heater_V, now()

    # -- configuration setters -----------------------------------------------------
    async def _set_load(self, load_g: float) -> None:
        if not (load_g != load_g or (math.isfinite(load_g) and load_g >= 0)):
            raise RigRefused(f"load {load_g!r} g: give the hanging mass in g (>= 0), or NaN for not declared")
        self._invalidate()
        await self._job(self.session.declare_load, float(load_g))

    async def _set_period(self, period_s: float) -> None:
        if not (math.isfinite(period_s) and 0 < period_s < self._window_s):
            raise RigRefused(f"sampling period {period_s!r} s: give a period > 0 s and shorter than the "
                             f"integration time ({self._window_s:g} s), so every acquisition holds a sample")
        if self._staged:
            self._invalidate()
            await self._job(self.session.set_sampling, float(period_s))
        self._period_s = float(period_s)

    async def _set_window(self, window_s: float) -> None:
        if not (math.isfinite(window_s) and window_s > self._period_s):
            raise RigRefused(f"integration time {window_s!r} s: give a window longer than the sampling period "
                             f"({self._period_s:g} s), so every acquisition holds a sample")
        self._invalidate()
        self._window_s = float(window_s)

    # -- staging ----------------------------------------------------------------------
    async def _stage_rig(self) -> None:
        self._staged += 1
        if self._staged > 1:
            return
        try:
            await self._job(self.session.ensure_position)
            await self._job(self.session.set_sampling, self._period_s)
        except BaseException:
            self._staged -= 1
            raise
        self._invalidate()

    async def _unstage_rig(self) -> None:
        if self._staged == 0:
            return
        self._staged -= 1
        if self._staged:
            return
        self._invalidate()
        if self.session.link is not None:
            await self._send_stop()
            await self._job(self.session.set_sampling, 0.0)

    @AsyncStatus.wrap
    async def stage(self) -> None:
        """Twist zero known, sampling on (see the module contract)."""
        await self._stage_rig()

    @AsyncStatus.wrap
    async def unstage(self) -> None:
        """The last unstage: STOP (motor halted, heater off), sampling off."""
        await self._unstage_rig()

    # -- acquisitions ------------------------------------------------------------------
    async def acquisition(self, reader: str) -> Acquisition:
        """The acquisition ``reader`` (a quantity name) reports: the current one, unless
        ``reader`` has reported it already or none is current; then a new one."""
        if self._lock is None:
            self._lock = asyncio.Lock()
        async with self._lock:
            if self._current is None or reader in self._reported:
                self._require_idle()
                acq = await self._job(self.session.acquire, self._window_s)
                self._current, self._reported = acq, set()
                self._remember(acq)
            self._reported.add(reader)
            return self._current

    def _remember(self, acq: Acquisition) -> None:
        self._by_time[acq.wall_time] = acq
        self._order.append(acq.wall_time)
        while len(self._order) > KEEP_ACQUISITIONS:
            self._by_time.pop(self._order.popleft(), None)

    def acquisition_at(self, timestamp: float) -> Acquisition | None:
        """The acquisition whose reading carries this timestamp (None: not one of this rig's,
        or older than the last :data:`KEEP_ACQUISITIONS`)."""
        return self._by_time.get(timestamp)

    # -- plain Python (no plan needed) ---------------------------------------------------
    def declare_twist(self, turns: float = 0.0) -> None:
        """Declare the twist the TSA holds now (turns; 0 = strings hanging untwisted): the
        answer to the device's position-unknown question. Blocks until the device took it."""
        self.session.submit(self.session.declare_twist, float(turns)).result()

    def clear_fault(self) -> None:
        """Clear a latched device fault (and drop waiting commands), after checking the rig."""
        self.session.submit(self.session.clear_fault).result()

    def close(self) -> None:
        """STOP, sampling off, position kept for the next open, port closed."""
        self.session.close()
