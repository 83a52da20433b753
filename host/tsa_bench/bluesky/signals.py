"""The signals of a rig: soft signals whose values come from the rig session.

Units are given to each signal (its descriptor's ``units``); see :mod:`.device`.

Contract: :class:`RigBackend` is an ophyd-async soft backend whose value comes from an
async getter returning ``(value, timestamp)`` (POSIX s), called on every read (never a
cached monitor), and whose descriptor carries units, precision and, once known, limits
(``control`` and ``display``: the bench file's and the device's, the tighter). Its
source is ``tsa-bench:<port>#<quantity>`` (:mod:`.sources`).
:class:`SampledSignal` is a read-only signal of such a backend that is never cached:
staging it stages the rig (sampling on) instead of starting a monitor.
"""

from __future__ import annotations

import math
import time
from collections.abc import Awaitable, Callable
from typing import Any

from bluesky.protocols import Reading
from ophyd_async.core import AsyncStatus, SignalR, SoftSignalBackend

from tsa_bench.bluesky.sources import source_of

Getter = Callable[[], Awaitable[tuple[Any, float]]]


class RigBackend(SoftSignalBackend):
    """A soft backend read through ``getter`` (see the module contract)."""

    def __init__(self, datatype: type, initial: Any, *, port: str, quantity: str, units: str,
                 precision: int | None = None, getter: Getter | None = None,
                 setter: Callable[[Any], Awaitable[None]] | None = None) -> None:
        super().__init__(datatype, initial, units=units, precision=precision, setter=setter)
        self._port, self._quantity, self._read = port, quantity, getter

    def set_limits(self, low: float | None, high: float | None) -> None:
        """Control and display limits for the descriptor (None: unbounded on that side)."""
        rng = {"low": -math.inf if low is None else float(low), "high": math.inf if high is None else float(high)}
        self.metadata["limits"] = {"control": dict(rng), "display": dict(rng)}

    def source(self, name: str, read: bool) -> str:
        return source_of(self._port, self._quantity)

    async def get_reading(self) -> Reading:
        if self._read is not None:
            value, stamp = await self._read()
            self.reading = Reading(value=self.converter.write_value(value), timestamp=stamp, alarm_severity=0)
            if self.callback:
                self.callback(self.reading)
        return self.reading

    async def get_value(self) -> Any:
        return (await self.get_reading())["value"]


def rig_signal(datatype: type, initial: Any, *, port: str, quantity: str, units: str, precision: int | None = None,
               getter: Getter | None = None, name: str = "") -> SignalR:
    """A read-only signal of a :class:`RigBackend` (cached when staged: for positions)."""
    return SignalR(RigBackend(datatype, initial, port=port, quantity=quantity, units=units, precision=precision,
                              getter=getter), name=name, timeout=None)


class SampledSignal(SignalR):
    """A measured quantity (length, resistance, ...): every read is an acquisition
    (:meth:`tsa_bench.bluesky.device.TsaRig.acquisition`); staging it stages its rig."""

    def __init__(self, backend: RigBackend, stage: Callable[[], Awaitable[None]],
                 unstage: Callable[[], Awaitable[None]], name: str = "") -> None:
        super().__init__(backend, timeout=None, name=name)
        self._stage_rig, self._unstage_rig = stage, unstage

    @AsyncStatus.wrap
    async def stage(self) -> None:
        """Stage the rig (sampling on, twist zero known); no monitor is started."""
        await self._stage_rig()

    @AsyncStatus.wrap
    async def unstage(self) -> None:
        """Unstage the rig (the last unstage: STOP, sampling off)."""
        await self._unstage_rig()

    async def read(self, cached: bool | None = None) -> dict[str, Reading]:
        """A fresh reading (never a cached one): see :meth:`TsaRig.acquisition`."""
        return {self.name: await self._connector.backend.get_reading()}

    async def get_value(self, cached: bool | None = None) -> Any:
        return (await self._connector.backend.get_reading())["value"]


def now() -> float:
    """POSIX time now (the timestamp of readings that are not acquisitions)."""
    return time.time()
