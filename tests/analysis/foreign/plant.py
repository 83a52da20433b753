"""Assemble the independent plant: rig + effects (in stage order) + sensor noise.

Units: as :mod:`tests.analysis.foreign.rig`. Returns the measured length (mm) and
resistance (ohm, NaN while the heater is on, as a bench would flag it); ``noise=False``
returns the noise-free outputs (NaN nowhere).
"""

from __future__ import annotations

import numpy as np

from tests.analysis.foreign.effects import STAGES, Effect, PlantRun
from tests.analysis.foreign.rig import Rig, resistance_ohm, tsa_length_mm
from tests.analysis.foreign.walks import History


def _noise(rng: np.random.Generator, sd: float, ar: float, n: int) -> np.ndarray:
    """Gaussian noise of standard deviation ``sd``, AR(1)-correlated with coefficient ``ar``."""
    e = rng.normal(0.0, sd * np.sqrt(1.0 - ar * ar), n)
    if ar:
        from scipy.signal import lfilter
        e = lfilter([1.0], [1.0, -ar], e)
        e[0] = rng.normal(0.0, sd)
    return e


def run_plant(rig: Rig, h: History, effects: list[Effect] = (), seed: int = 0, noise: bool = True
              ) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    run = PlantRun(rig, h.t, h.turns.copy(), h.load_g, h.volts, h.moving, h.turns.copy(), h.turns.copy(), rng=rng)
    by_stage = {s: [e for e in effects if e.stage == s] for s in STAGES}
    for e in by_stage["motor"]:
        e.apply(run)
    run.twist = run.turns.copy()
    for e in by_stage["twist"]:
        e.apply(run)
    run.length = tsa_length_mm(rig, run.twist, h.load_g)
    for e in by_stage["length"]:
        e.apply(run)
    run.resistance = resistance_ohm(rig, run.length, run.twist)
    for e in by_stage["resistance"]:
        e.apply(run)
    for e in by_stage["sensor"]:
        e.apply(run)
    if not noise:
        return run.length, run.resistance
    length = run.length + _noise(rng, rig.length_noise_mm, rig.noise_ar, len(h))
    res = run.resistance + _noise(rng, rig.resistance_noise_ohm, rig.noise_ar, len(h))
    if rig.length_step_mm > 0:
        length = np.round(length / rig.length_step_mm) * rig.length_step_mm
    if rig.resistance_step_ohm > 0:
        res = np.round(res / rig.resistance_step_ohm) * rig.resistance_step_ohm
    res[h.volts > 0] = np.nan
    return length, res
