"""Input histories of the protocol shapes a study point simulates.

Units: time in s, twist in turns, heater voltage in V, load in g.

Contract: :func:`history` turns ``config["protocol"]`` into a sampled input history
(``t``, ``turns``, ``heater_voltage``, ``load_g``, ``motor_moving``, ``segment``, one
sample per ``dt_s``; moves at 3.33 turns/s as on the thesis rig) for the shapes of
:data:`tsa_bench.sweep.schema.SHAPES`:

* ``staircase``: the thesis's step-duration run (2.5.2): rest at ``lo_turns``, then
  ``cycles`` staircases lo -> hi -> lo in ``step_turns`` steps held ``hold_s`` each;
* ``lifetime``: the thesis's cycling test (2.5.2): ``cycles`` of 15 -> 25 -> 15 turns in
  2-turn steps with 1 s pauses;
* ``diagnostic``: ``repeats`` blocks of a staircase up and down (holds ``hold_s``),
  ``cycles`` fast cycles, a load step (``load_g`` -> 60 % -> back) and two heater steps
  (6 V, 8 V for 20 s, each followed by a 2 x ``hold_s`` cool-down) - every kind of
  excitation diagnose looks for, in each block.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

RATE_TURNS_PER_S = 3.33


def steps_of(protocol: dict[str, Any]) -> list[tuple]:
    """Steps ``("move", turns)``, ``("hold", s)``, ``("heater", V, s)``, ``("load", g)`` of a shape."""
    shape = protocol["shape"]
    if shape == "staircase":
        lo, hi, step = float(protocol["lo_turns"]), float(protocol["hi_turns"]), float(protocol["step_turns"])
        if step <= 0 or hi <= lo:
            raise ValueError(f"staircase needs step_turns > 0 and hi_turns > lo_turns (got lo {lo:g}, hi {hi:g}, "
                             f"step {step:g})")
        up = [float(x) for x in np.arange(lo + step, hi + 1e-9, step)]
        targets = up + up[-2::-1] + [lo]
        hold = float(protocol["hold_s"])
        s = [("hold", 5.0), ("move", lo), ("hold", float(protocol["rest_s"]))]
        for _ in range(int(protocol["cycles"])):
            for x in targets:
                s += [("move", x), ("hold", hold)]
        return s
    if shape == "lifetime":
        from tsa_bench.reproduce.experiments import lifetime_steps

        return lifetime_steps(int(protocol["cycles"]))
    if shape == "diagnostic":
        hold, load = float(protocol["hold_s"]), float(protocol["load_g"])
        s: list[tuple] = [("hold", 20.0)]
        for _ in range(int(protocol["repeats"])):
            for x in (10, 20, 30, 40, 30, 20, 10):
                s += [("move", float(x)), ("hold", hold)]
            for _ in range(int(protocol["cycles"])):
                s += [("move", 35.0), ("hold", 0.5), ("move", 10.0), ("hold", 0.5)]
            s += [("hold", hold), ("load", 0.6 * load), ("hold", hold), ("move", 25.0), ("hold", hold),
                  ("move", 10.0), ("hold", hold), ("load", load), ("hold", hold), ("move", 20.0)]
            for volts in (6.0, 8.0):
                s += [("heater", volts, 20.0), ("hold", 2 * hold)]
            s += [("move", 10.0), ("hold", hold)]
        return s
    raise ValueError(f"unknown protocol shape {shape!r}")


def history(protocol: dict[str, Any]) -> dict[str, np.ndarray]:
    """The sampled input history of ``protocol`` (module contract)."""
    dt = float(protocol["dt_s"])
    if not dt > 0:
        raise ValueError(f"protocol.dt_s must be > 0, got {dt}")
    load = float(protocol["load_g"])
    t, turns, volts, loads, moving, seg = [], [], [], [], [], []
    now, pos = 0.0, 0.0
    for k, st in enumerate(steps_of(protocol)):
        if st[0] == "load":
            load = float(st[1])
            continue
        if st[0] == "move":
            target = float(st[1])
            n = max(1, int(math.ceil(abs(target - pos) / RATE_TURNS_PER_S / dt)))
            path = pos + (target - pos) * np.arange(1, n + 1) / n
            v, mv = 0.0, 1
            pos = target
        else:
            v = float(st[1]) if st[0] == "heater" else 0.0
            n = max(1, int(round(float(st[2] if st[0] == "heater" else st[1]) / dt)))
            path = np.full(n, pos)
            mv = 0
        t.append(now + dt * np.arange(n)); turns.append(path); volts.append(np.full(n, v))
        loads.append(np.full(n, load)); moving.append(np.full(n, mv, np.uint8)); seg.append(np.full(n, k, np.int32))
        now += n * dt
    return {"t": np.concatenate(t), "turns": np.concatenate(turns), "heater_voltage": np.concatenate(volts),
            "load_g": np.concatenate(loads), "motor_moving": np.concatenate(moving), "segment": np.concatenate(seg)}
