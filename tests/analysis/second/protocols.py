"""Input histories of the second generator: pyramids and amplitude sweeps.

Units: s, turns, turns/s, g.

A ``pyramid`` climbs to the top twist in unequal steps with holds that shorten as it
climbs, comes down in other steps, runs a few fast triangles in the middle range, changes
the load (each load in turn, a hold after each) and repeats a smaller pyramid. A
``sweep`` runs triangles of growing amplitude at alternating speeds with short holds at
the turning points and a long one at zero, changing the load between groups. Moves are
at constant speed (no ramp); every move and every hold is a segment; ``moving`` is 1
during a move. Amplitudes and hold times are drawn from the seed.
"""

from __future__ import annotations

import json

import numpy as np

from tests.analysis.foreign.walks import History as Inputs   # the input history's container, not its equations
from tests.analysis.second.rigs import Rig, full_twist_turns


class _Tape:
    def __init__(self, rate_hz: float, load_g: float) -> None:
        self.dt, self.now, self.pos, self.load = 1.0 / rate_hz, 0.0, 0.0, load_g
        self.rows: list[tuple[float, float, float, int, int]] = []
        self.segments: list = []

    def _segment(self, kind: str, t0: float, params: dict) -> None:
        self.segments.append((len(self.segments), kind, t0, self.now - self.dt, params))

    def move(self, target: float, speed: float) -> None:
        t0, start = self.now, self.pos
        steps = max(1, int(np.ceil(abs(target - start) / speed / self.dt)))
        for k in range(1, steps + 1):
            self.rows.append((self.now, start + (target - start) * k / steps, self.load, 1, len(self.segments)))
            self.now += self.dt
        self.pos = target
        self._segment("move_to", t0, {"turns": target})

    def hold(self, seconds: float) -> None:
        t0 = self.now
        for _ in range(max(1, int(round(seconds / self.dt)))):
            self.rows.append((self.now, self.pos, self.load, 0, len(self.segments)))
            self.now += self.dt
        self._segment("hold", t0, {"duration_s": seconds})

    def set_load(self, load_g: float) -> None:
        self.load = load_g

    def done(self) -> Inputs:
        a = np.array(self.rows)
        return Inputs(a[:, 0], a[:, 1], np.zeros(len(a)), a[:, 2], a[:, 3].astype(bool), a[:, 4].astype(int),
                      self.segments)


def _start(rig: Rig, seed: int, first_hold_s: float) -> tuple[np.random.Generator, float, _Tape]:
    """The seeded draws, the top twist (a share of the fully twisted one under the heaviest load), the tape."""
    tape = _Tape(rig.rate_hz, rig.loads_g[0])
    tape.hold(first_hold_s)
    return np.random.default_rng(seed), rig.top_fraction * min(full_twist_turns(rig, m) for m in rig.loads_g), tape


def pyramid(rig: Rig, seed: int, minutes: float = 12.0) -> Inputs:
    rng, top, tape = _start(rig, seed, 25.0)
    budget = minutes * 60.0
    scale = 1.0
    while tape.now < budget:
        for load in rig.loads_g:
            if tape.now >= budget:
                break
            if load != tape.load:
                tape.move(0.0, 3.0)
                tape.set_load(load)
                tape.hold(rng.uniform(40.0, 70.0))
            ups = np.sort(rng.uniform(0.15, 1.0, 4)) * top * scale
            for k, x in enumerate(ups):
                tape.move(float(x), rng.uniform(1.0, 3.0))
                tape.hold(float(rng.uniform(30.0, 55.0) * (1.0 - 0.15 * k)))
            for x in np.sort(rng.uniform(0.1, 0.9, 3))[::-1] * top * scale:
                tape.move(float(x), rng.uniform(1.0, 3.0))
                tape.hold(float(rng.uniform(15.0, 40.0)))
            lo, hi = 0.3 * top * scale, 0.7 * top * scale
            for _ in range(int(rng.integers(2, 4))):
                tape.move(hi, 4.0)
                tape.hold(1.0)
                tape.move(lo, 4.0)
                tape.hold(1.0)
            tape.hold(float(rng.uniform(20.0, 40.0)))
        scale = 0.8
    tape.move(0.0, 3.0)
    tape.hold(20.0)
    return tape.done()


def sweep(rig: Rig, seed: int, minutes: float = 12.0) -> Inputs:
    rng, top, tape = _start(rig, seed, 30.0)
    budget = minutes * 60.0
    k = 0
    while tape.now < budget:
        load = rig.loads_g[k % len(rig.loads_g)]
        if load != tape.load:
            tape.set_load(load)
            tape.hold(rng.uniform(45.0, 75.0))
        for amp in (0.35, 0.6, 0.85, 1.0):
            speed = 1.2 if k % 2 else 3.5
            tape.move(float(amp * top * rng.uniform(0.9, 1.0)), speed)
            tape.hold(float(rng.uniform(6.0, 20.0)))
            tape.move(float(0.1 * top), speed)
            tape.hold(float(rng.uniform(6.0, 20.0)))
        tape.move(0.0, 2.0)
        tape.hold(float(rng.uniform(40.0, 70.0)))
        k += 1
    return tape.done()


PROTOCOLS = {"pyramid": pyramid, "sweep": sweep}


def segment_rows(h: Inputs) -> list[tuple]:
    return [(i, kind, a, b, 1, -1, f"second:{i}", json.dumps(p)) for i, kind, a, b, p in h.segments]
