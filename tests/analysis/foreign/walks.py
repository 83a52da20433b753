"""Random rotation walks: the input history the independent generator feeds its plant.

Units: time in s, twist in turns, speed in turns/s, load in g, heater voltage in V.

A walk starts untwisted under the rig's first load, then moves to random twist targets
(a random walk over [0, reach x full twist]) at random speeds, holding a random time
(log-uniform 0.5-25 s, now and then a long hold of 1-2 min) after each move; the load
changes to the rig's other masses at evenly spread times (each change followed by a
hold); it ends untwisted. Each move and hold is one segment. ``heater`` adds a few
voltage steps held at a fixed twist (for thermal cases).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from tests.analysis.foreign.rig import Rig, full_twist_turns


@dataclass
class History:
    t: np.ndarray
    turns: np.ndarray
    volts: np.ndarray
    load_g: np.ndarray
    moving: np.ndarray
    segment: np.ndarray
    segments: list = field(default_factory=list)   # (index, kind, t_start, t_end, params)

    def __len__(self) -> int:
        return len(self.t)


class _Builder:
    def __init__(self, rate_hz: float, load_g: float) -> None:
        self.dt = 1.0 / rate_hz
        self.now = 0.0
        self.pos = 0.0
        self.load = load_g
        self.volts = 0.0
        self.cols: dict[str, list] = {k: [] for k in ("t", "turns", "volts", "load", "moving", "segment")}
        self.segments: list = []

    def _emit(self, turns: float, moving: int) -> None:
        c = self.cols
        c["t"].append(self.now)
        c["turns"].append(turns)
        c["volts"].append(self.volts)
        c["load"].append(self.load)
        c["moving"].append(moving)
        c["segment"].append(len(self.segments))
        self.now += self.dt

    def move(self, target: float, speed: float) -> None:
        t0 = self.now
        n = max(1, int(np.ceil(abs(target - self.pos) / speed / self.dt)))
        for k in range(1, n + 1):
            self._emit(self.pos + (target - self.pos) * k / n if k < n else target, 1)
        self.segments.append(("move", t0, self.now, {"to_turns": target, "rate_turns_per_s": speed}))
        self.pos = target

    def hold(self, seconds: float, kind: str = "hold", **params) -> None:
        t0 = self.now
        for _ in range(max(1, int(round(seconds / self.dt)))):
            self._emit(self.pos, 0)
        self.segments.append((kind, t0, self.now, {"duration_s": seconds, **params}))

    def history(self) -> History:
        c = self.cols
        segs = [(i, k, a, b, p) for i, (k, a, b, p) in enumerate(self.segments)]
        return History(np.array(c["t"]), np.array(c["turns"]), np.array(c["volts"], float), np.array(c["load"], float),
                       np.array(c["moving"], np.uint8), np.array(c["segment"], np.int32), segs)


def random_walk(rig: Rig, seed: int, minutes: float = 20.0, heater_V: tuple[float, ...] = (),
                heat_at: float = 0.5) -> History:
    """A random rotation walk of about ``minutes`` on ``rig`` (see the module docstring); the
    heater steps ``heater_V`` (60 s each) start at the fraction ``heat_at`` of the time."""
    rng = np.random.default_rng(seed)
    top = rig.reach * min(full_twist_turns(rig, m) for m in rig.loads_g)
    b = _Builder(rig.rate_hz, rig.loads_g[0])
    b.hold(20.0)
    total = 60.0 * minutes
    changes = [total * (k + 1) / len(rig.loads_g) for k in range(len(rig.loads_g) - 1)]
    heat_at = total * heat_at if heater_V else None
    while b.now < total - 60.0:
        if changes and b.now >= changes[0]:
            changes.pop(0)
            b.load = rig.loads_g[len(rig.loads_g) - 1 - len(changes)]
            b.hold(45.0, kind="prompt", load_g=b.load)
            continue
        if heat_at is not None and b.now >= heat_at:
            heat_at = None
            for v in heater_V:
                b.volts = v
                b.hold(60.0, kind="heater", voltage_V=v)
            b.volts = 0.0
            b.hold(90.0, kind="heater", voltage_V=0.0)
            continue
        step = rng.uniform(-0.45, 0.45) * top
        if rng.random() < 0.15:
            step = rng.uniform(0.85, 1.0) * top - b.pos
        target = float(np.clip(b.pos + step, 0.0, top))
        if abs(target - b.pos) < 0.5:
            target = float(np.clip(b.pos + (2.0 if b.pos < top / 2 else -2.0), 0.0, top))
        b.move(round(target, 3), float(rng.choice([0.8, 1.5, 2.5, 4.0, 5.0])))
        hold = float(np.exp(rng.uniform(np.log(0.5), np.log(25.0))))
        if rng.random() < 0.08:
            hold = float(rng.uniform(60.0, 120.0))
        b.hold(hold)
    b.move(0.0, 3.0)
    b.hold(20.0)
    return b.history()


def segments_table(h: History) -> list[tuple]:
    """Rows of the run file's /segments table."""
    return [(i, kind, a, b, 1, -1, f"walk:{i}", json.dumps(p)) for i, kind, a, b, p in h.segments]
