"""What one diagnosis holds fixed once the data are read: runs, outputs, noise, holdout,
subsamples, resampling units; the engine's constants; residual tests of a replay.

Units: length mm, resistance ohm; improvements in noise variances per sample.

Contract: :class:`Context` builds the calibration subsample (:data:`N_CAL` samples over
all runs) and the smaller one candidate refits use (:data:`N_REFIT`), the held-out
resampling units, and offers ``scores`` (held-out unit scores of a config), ``compare``
(block bootstrap, :mod:`tsa_bench.analysis.scoring`) and ``residual_tests`` (structure of
a replay's residual per output, :mod:`tsa_bench.analysis.structure`). The constants are
the decision rule's (docs/diagnose.md).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from tsa_bench.analysis.calibrate import Problem
from tsa_bench.analysis.families import RunScale
from tsa_bench.analysis.holdout import Holdout
from tsa_bench.analysis.inputs import RunInputs
from tsa_bench.analysis.modelspec import enabled_effects, get_value
from tsa_bench.analysis.noise import RELEVANT, Noise
from tsa_bench.analysis.replay import ReplayCache, replay_samples
from tsa_bench.analysis.scoring import Comparison, Scores, all_units, compare, unit_scores
from tsa_bench.analysis.settling import Component, conditional, hold_groups, variance_component
from tsa_bench.analysis.signals import RunBases, last_direction
from tsa_bench.analysis.structure import jumps, ljung_box, structure_test

#: relevance floor of an improvement: (half a noise RMS)^2, in noise variances per sample
FLOOR = RELEVANT ** 2
N_CAL = 2000          # calibration subsample (all runs)
N_REFIT = 1000        # subsample for candidate refits (the named one is then polished on N_CAL)
REFIT_MAX = 8          # forms refitted per iteration (every form of the leader, the best of each other family)
REFIT_NFEV = 20       # function evaluations per refit
#: other effects are refitted when their screen reaches this share of the leader's: every one that
#: screens at all (SCREEN_MIN), since a linear screen can miss an effect whose refit explains a lot
#: (the load dependence changes the calibration it is screened against)
CONTENDER = 0.0
#: a form whose companion only acts through it (the resistance's temperature coefficient needs the
#: strings to heat) is also refitted together with it
COMPANIONS = {"thermal_dynamics": ("resistance_temperature",)}
SCREEN_MIN = 0.01     # a form's signature must explain at least this share of the residual
N_BOOT = 1000
#: a candidate that makes an output's held-out error worse by more than HARM_REL of it (and the floor),
#: in HARM_P of the resamples, is rejected: a cure must not damage another output noticeably
HARM_P = 0.5
HARM_REL = 0.1
UNITS = {"length": "mm", "resistance": "ohm"}
#: effects on the resistance alone are not candidates while the length error, through dR/dX,
#: explains at least this share of the resistance residual's structure
PROPAGATED = 0.5
Progress = Callable[[str], None]


def residual_structure(res: np.ndarray, noise: Noise, rate: float, bases: dict[str, np.ndarray], moving: np.ndarray) -> dict:
    t = structure_test(res, noise, rate, bases)
    t["ljung_box_p"] = ljung_box(res)[1]
    t["jumps"] = jumps(res, noise, moving)
    if not t["structured"]:
        t["follows"] = []
    return t


class Context:
    """Everything fixed once the inputs, holdout and noise are known (module docstring)."""

    def __init__(self, inputs: list[RunInputs], outputs: tuple[str, ...], noise: dict[str, Noise], hold: Holdout,
                 seed: int) -> None:
        self.inputs, self.outputs, self.noise, self.hold, self.seed = inputs, outputs, noise, hold, seed
        self.sigma = {o: noise[o].rms for o in outputs}
        n_total = sum(len(r) for r in inputs)
        self.cache = ReplayCache()
        self.problem = self._problem(N_CAL, 300, n_total)
        self.small = self._problem(N_REFIT, 200, n_total)
        self.units = all_units(inputs)
        self.rate = float(np.median([r.rate_hz for r in inputs]))
        self.moving = np.concatenate([r.moving for r in inputs])
        self.kinds = {k for k, v in hold.kinds.items() if v["train"] + v["heldout"] > 0}
        self.induced: set[str] = set()   # outputs structured only through the joint fit with the other
        self.source: set[str] = set(outputs)   # outputs structured in the judged model (what may be blamed)
        self.form_bars: dict[str, tuple[float, str]] = {}   # output -> (form spread of a named effect, its name)
        self._hold_arrays: tuple[np.ndarray, ...] | None = None

    def _problem(self, n_cal: int, at_least: int, n_total: int) -> Problem:
        """A calibration problem on ~``n_cal`` samples shared out over the runs by length (at least
        ``at_least`` each); on long runs the twist's turning points are replayed for the state only."""
        picked = [replay_samples(r, len(r), max(at_least, n_cal * len(r) // max(1, n_total))) for r in self.inputs]
        idx = [p[0] for p in picked]
        return Problem(self.inputs, idx, [~r.heldout[i] for r, i in zip(self.inputs, idx)], self.sigma, self.outputs,
                       self.cache, [p[1] for p in picked])

    def scores(self, cfg: Mapping[str, Any], keep_sims: bool = True) -> Scores:
        """Held-out unit scores of ``cfg``; with ``keep_sims`` also its full-resolution replays."""
        return unit_scores(cfg, self.inputs, self.units, self.sigma, self.outputs, cache=self.cache,
                           keep_sims=keep_sims)

    def compare(self, a: Scores, b: Scores) -> Comparison:
        return compare(a, b, FLOOR, N_BOOT, self.seed)

    def residual(self, sims: list[dict], o: str) -> np.ndarray:
        """Measured minus replayed ``o`` over every run (NaN where not scored)."""
        parts = [np.where(r.scored, r.output(o) - s[o], np.nan) for r, s in zip(self.inputs, sims)]
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def _holds(self) -> tuple[np.ndarray, ...]:
        if self._hold_arrays is None:
            groups, off = [], 0
            for r in self.inputs:
                g = hold_groups(r)
                groups.append(g + off)
                off += int(g[-1]) + 1 if len(g) else 0
            t_off, ts = 0.0, []
            for r in self.inputs:
                ts.append(r.t - r.t[0] + t_off)
                t_off += r.duration_s + 1.0
            cat = np.concatenate
            self._hold_arrays = (cat(groups), cat([r.turns for r in self.inputs]), cat([r.load_g for r in self.inputs]),
                                 cat(ts), cat([r.scored & ~r.heldout for r in self.inputs]),
                                 cat([r.scored & r.heldout for r in self.inputs]),
                                 cat([last_direction(r)[:, 0] for r in self.inputs]))
        return self._hold_arrays

    def component(self, sims: list[dict], o: str, res: np.ndarray | None = None) -> Component:
        """The hold-to-hold variance component of the residual of ``o`` (:mod:`tsa_bench.analysis.settling`)."""
        groups, turns, load, t, train, held, direction = self._holds()
        res = self.residual(sims, o) if res is None else res
        r0 = float(np.nanmedian(np.concatenate([r.resistance for r in self.inputs])))
        level = self.inputs[0].length if len(self.inputs) == 1 else np.concatenate([r.length for r in self.inputs])
        return variance_component(o, res, train, held, groups, turns, load, t, self.noise[o], RunBases(self.inputs, r0),
                                  level, direction)

    def residual_tests(self, sims: list[dict], r0: float, settle: Mapping[str, Component] | None = None) -> dict:
        """Structure of each output's residual; for an output with a hold-to-hold component in ``settle``
        (fitted on these sims) the residual less each hold's predicted offset is tested."""
        bases = RunBases(self.inputs, r0)
        out = {}
        for o in self.outputs:
            res = self.residual(sims, o)
            comp = (settle or {}).get(o)
            if comp is not None and comp.follows:     # offsets that follow something are a misfit: left in
                comp = None
            if comp is not None:
                groups, turns, load, t, _, _, direction = self._holds()
                res = conditional(comp, res, groups, turns, load, t, self.noise[o], direction)
            out[o] = residual_structure(res, self.noise[o], self.rate, bases, self.moving)
            if comp is not None:
                out[o]["hold_offsets_removed"] = comp.tau
            out[o]["undriven"] = self.undriven
        return out

    @property
    def undriven(self) -> bool:
        """True when neither twist nor heater changes in any run: nothing the model knows drives the actuator."""
        return all(np.ptp(r.turns[r.scored]) == 0 if r.scored.any() else True for r in self.inputs) and \
            all(np.ptp(np.nan_to_num(r.volts)) == 0 for r in self.inputs)


def run_scale(ctx: Context, cfg: Mapping[str, Any]) -> RunScale:
    from tsa_bench.analysis.quasistatic import static_length
    from tsa_bench.sim.kinematics import NEWTON_PER_GRAM
    tw = np.concatenate([r.turns for r in ctx.inputs])
    ld = np.concatenate([r.load_g for r in ctx.inputs])
    sel = np.linspace(0, len(tw) - 1, min(len(tw), 2000)).astype(int)
    l0, r0 = get_value(cfg, "geometry.untwisted_length_mm"), get_value(cfg, "geometry.radius_mm")
    k = get_value(cfg, "string_compliance.stiffness_N")
    on = set(enabled_effects(cfg))
    x = static_length(l0, r0, k, tw[sel], ld[sel], "string_compliance" in on, "radius_growth" in on)
    r2 = r0 * r0 * (l0 / x if "radius_growth" in on else 1.0)
    torque = ld[sel] * NEWTON_PER_GRAM * 2 * np.pi * np.abs(tw[sel]) * r2 / x * 1e-3
    speeds = np.concatenate([(np.abs(np.diff(r.turns)) / np.maximum(np.diff(r.t), 1e-9))[r.moving[1:]]
                             for r in ctx.inputs])
    speed = [float(np.max(speeds, initial=0.0))]
    typical = float(np.median(speeds[speeds > 0])) if np.any(speeds > 0) else 1.0
    res_level = get_value(cfg, "geometry.resistance_ohm")
    return RunScale(float(np.max(np.abs(tw))), float(np.max(torque, initial=0.0)), float(max(speed)), typical,
                    float(sum(r.duration_s for r in ctx.inputs)), res_level,
                    ctx.noise["resistance"].rms if "resistance" in ctx.outputs else 1e-3,
                    float(np.median(x)), ctx.noise["length"].rms if "length" in ctx.outputs else 0.05)


