"""The second generator's cases, what an honest diagnosis says of each, and the rates over many.

Units: as :mod:`tests.analysis.second.rigs`.

:func:`make` writes one case's run file (contract of docs/run-format.md, plain h5py) and
returns a :class:`Case`: ``kind`` ("clean", "library" for a library family in the
generator's own form, "artefact" for a sensor artefact a physical effect can mimic,
"outside" for an effect outside the library) and ``family`` (what must be named; None for
clean and outside). :func:`judge` scores a diagnosis of a case: ``detected`` (the family
is named, or is a named cause's confusable alternative), ``wrong`` (a confident name,
confidence above 0.5, of something not true, alternatives included), ``alarm`` (anything
named on a clean run) and ``confident`` (a name with confidence above 0.5).
:func:`rates` gives the rates with 95 % Wilson intervals.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tests.analysis.runfiles import write_contract_run
from tests.analysis.second import effects as fx
from tests.analysis.second.protocols import PROTOCOLS, Inputs, segment_rows
from tests.analysis.second.rigs import GRAVITY, RIGS, Rig, helix_length_mm, resistance_ohm
from tsa_bench.sweep.stats import wilson

#: name -> (rig, protocol, effect builder or None, kind)
CASES = {
    "clean-long": ("long-6ply-20ohm", "pyramid", None, "clean"),
    "clean-short": ("short-2ply-1ohm", "sweep", None, "clean"),
    "clean-mid": ("mid-scp-uhmwpe", "pyramid", None, "clean"),
    "power-transient": ("mid-scp-uhmwpe", "sweep", fx.power_transient, "library"),
    "log-creep": ("long-6ply-20ohm", "pyramid", fx.log_creep, "library"),
    "dahl-friction": ("short-2ply-1ohm", "pyramid", fx.dahl_friction, "library"),
    "sqrt-wear": ("mid-scp-uhmwpe", "pyramid", fx.sqrt_wear, "library"),
    "r-gain-drift": ("long-6ply-20ohm", "sweep", fx.resistance_gain_drift, "artefact"),
    "l-zero-drift": ("mid-scp-uhmwpe", "sweep", fx.length_zero_drift, "artefact"),
    "mains-beat": ("mid-scp-uhmwpe", "pyramid", fx.mains_beat, "outside"),
    "contact-ripple": ("long-6ply-20ohm", "sweep", fx.contact_ripple, "outside"),
    "track-wave": ("short-2ply-1ohm", "pyramid", fx.track_wave, "outside"),
}
STAGES = ("twist", "length", "resistance", "sensor")


@dataclass
class Case:
    name: str
    path: Path
    kind: str
    family: str | None
    n: int


def simulate(rig: Rig, h: Inputs, effects: list[fx.Effect], seed: int, noise: bool = True
             ) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    pl = fx.Plant(rig, h, h.turns.copy(), np.zeros(len(h)), np.zeros(len(h)))
    for stage in STAGES:
        if stage == "length":
            pl.length = helix_length_mm(rig, pl.twist, h.load_g)
        if stage == "resistance":
            pl.resistance = resistance_ohm(rig, pl.length, pl.twist)
        for e in effects:
            if e.stage == stage:
                e.apply(pl, rng)
    if not noise:
        return pl.length, pl.resistance
    length = pl.length + rng.normal(0.0, rig.length_noise_mm, len(h))
    res = pl.resistance + rng.normal(0.0, rig.resistance_noise_ohm, len(h))
    if rig.length_step_mm:
        length = np.round(length / rig.length_step_mm) * rig.length_step_mm
    if rig.resistance_step_ohm:
        res = np.round(res / rig.resistance_step_ohm) * rig.resistance_step_ohm
    return length, res


def write(path: str | Path, h: Inputs, length: np.ndarray, res: np.ndarray) -> Path:
    n = len(h)
    cols = {"t": (h.t, "s"), "turns": (h.turns, "turn"), "length": (length, "mm"), "resistance": (res, "ohm"),
            "heater_voltage": (np.zeros(n), "V"), "load": (h.load_g * GRAVITY / 1000.0, "N"),
            "segment": (h.segment, "1"), "motor_moving": (h.moving.astype(np.uint8), "1"),
            "counter": (np.arange(n, dtype=np.uint32), "1")}
    return write_contract_run(path, cols, segment_rows(h), {
        "created": "2025-06-01T09:00:00+00:00", "backend": "import", "firmware": "", "exit_status": "success",
        "reason": "second independent generator"})


def make(name: str, path: str | Path, seed: int, minutes: float = 12.0) -> Case:
    """Write case ``name`` drawn from ``seed`` to ``path``."""
    rig_name, proto, build, kind = CASES[name]
    rig = RIGS[rig_name]
    h = PROTOCOLS[proto](rig, seed, minutes)
    effects = [build(np.random.default_rng(500 + seed), rig)] if build else []
    length, res = simulate(rig, h, effects, 900 + seed)
    return Case(name, write(path, h, length, res), kind, effects[0].family if effects else None, len(h))


def judge(case: Case, result) -> dict:
    """How a diagnosis of ``case`` scores (module docstring)."""
    named = [c for c in result.named]
    names = {c.effect for c in named}
    alts = {a["effect"] for c in named for a in getattr(c, "alternatives", [])}
    confident = [c for c in named if c.confidence > 0.5]
    truth = {case.family} if case.family else set()
    wrong = [c.effect for c in confident if c.effect not in truth]
    return {"case": case.name, "kind": case.kind, "family": case.family, "verdict": result.verdict,
            "named": sorted(names), "alternatives": sorted(alts),
            "detected": bool(case.family) and case.family in names | alts,
            "wrong": bool(wrong), "wrong_names": wrong, "alarm": case.kind == "clean" and bool(named),
            "confident": bool(confident), "summary": result.summary}


def rates(rows: list[dict]) -> dict[str, tuple[int, int, tuple[float, float]]]:
    """detection (library and artefact cases), wrong name (every run), false alarm (clean runs),
    confident name outside the library (outside cases): (k, n, 95 % interval)."""
    def rate(sel, key):
        k, n = sum(bool(r[key]) for r in sel), len(sel)
        return k, n, wilson(k, n)
    return {"detection": rate([r for r in rows if r["kind"] in ("library", "artefact")], "detected"),
            "wrong name": rate(rows, "wrong"),
            "false alarm": rate([r for r in rows if r["kind"] == "clean"], "alarm"),
            "outside named with confidence > 0.5": rate([r for r in rows if r["kind"] == "outside"], "confident")}
