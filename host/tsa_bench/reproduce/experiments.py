"""The thesis's experiments simulated on the bench presets, each run once and cached.

Units: twist in turns, heater voltage in V, load in g (N in run data), length in mm,
resistance in ohm, time in s.

Contract: a :class:`Lab` holds one ``plant`` mapping per preset (``configs/bench/<name>.yaml``
by default; the calibration passes modified copies) and simulates, on demand and once
each, the experiments the records refer to. Which preset plays which thesis actuator
is :data:`PRESET_FOR`. Every simulated run gets its own noise seed (from the Lab's seed
and the run's name), so run-to-run variability is that of independent runs. The
histories follow the shipped protocols (configs/protocols/) and the thesis text:

* ``sweep(ply, load)``: 2.4.2 twisting, 0 -> full -> 0 turns (3-ply 72 turns in 8-turn
  steps, 4-ply 81 in 9-turn steps), 5 s holds;
* ``heat(ply, load)``: 2.4.3, twist to full, 0 -> 8 -> 0 V in 1 V steps held 90 s,
  cool 120 s, untwist;
* ``scheme(n, load)``: 2.5.1, 20 -> 55 -> 20 turns in 5-turn steps held 180 s;
* ``steps(d)``: 2.5.2 step-duration runs (350 g, 15 -> 25 -> 15 turns in 2-turn steps);
* ``stiffness(ply)``: 2.3, loads 0 -> max -> 0 in 50 g steps held 60 s, no twist;
* ``lifetime()``: 2.5.2, 596 cycles (``quick``: 60) of 15 -> 25 -> 15 turns, 550 g;
* ``thermal(ply, load)``: a noise-free 8 V step at full twist, then cooling.

``quick`` shortens the long runs (fewer cycles, shorter holds) for tests; values from a
quick Lab are flagged by the table.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from tsa_bench.reproduce.runs import history, step_duration_steps, twist_heat_steps
from tsa_bench.sim.history import simulate
from tsa_bench.sim.kinematics import NEWTON_PER_GRAM
from tsa_bench.sim.plant import plant_from_config
from tsa_bench.rundata import RunData

ROOT = Path(__file__).resolve().parents[3]
BENCH_DIR = ROOT / "configs" / "bench"

#: which preset plays which thesis actuator
PRESET_FOR: dict[str, str] = {"ply3": "sim-3ply", "ply4": "sim-4ply", "scheme1": "sim-scheme1",
                              "scheme2": "sim-scheme2-4ply", "transient": "sim"}
PRESETS = tuple(dict.fromkeys(PRESET_FOR.values()))
FULL_TWIST = {3: (72.0, 8.0), 4: (81.0, 9.0)}       # ply -> (full twist, step) turns
LOADS = {3: (100.0, 150.0, 200.0), 4: (150.0, 200.0, 250.0)}
SCHEME_LOADS = {1: (450.0, 550.0), 2: (250.0, 350.0)}
DURATIONS_S = (2.4, 6.0, 17.0, 32.0, 98.0)
TRAINING_S = (6.0, 32.0)
MAX_VOLTAGE_V = 8.0


LIFETIME_CYCLES = 596


def lifetime_steps(cycles: int) -> list[tuple]:
    """2.5.2: 15 turns, 2 min rest, then ``cycles`` of 15 -> 25 -> 15 turns in 2-turn steps with 1 s pauses."""
    targets = [17.0, 19.0, 21.0, 23.0, 25.0, 23.0, 21.0, 19.0, 17.0, 15.0]
    steps: list[tuple] = [("hold", 5.0), ("move", 15.0), ("hold", 120.0)]
    for _ in range(cycles):
        for x in targets:
            steps += [("move", x), ("hold", 1.0)]
    return steps


def preset_plant(name: str, bench_dir: Path = BENCH_DIR) -> dict[str, Any]:
    """The ``plant`` mapping of ``<bench_dir>/<name>.yaml``."""
    doc = yaml.safe_load((bench_dir / f"{name}.yaml").read_text(encoding="utf-8"))
    return dict(doc["plant"])


def preset_for(conditions: dict[str, Any]) -> str:
    """The preset of a record's conditions: ply -> sim-3ply/sim-4ply, scheme -> Scheme presets, else sim."""
    if "scheme" in conditions and not isinstance(conditions["scheme"], list):
        return PRESET_FOR[f"scheme{int(conditions['scheme'])}"]
    if "ply" in conditions and not isinstance(conditions["ply"], list):
        return PRESET_FOR[f"ply{int(conditions['ply'])}"]
    return PRESET_FOR["transient"]


@dataclass
class SimRun:
    """One simulated run: its input history, plant output and in-memory run data."""

    name: str
    hist: dict[str, np.ndarray]
    out: dict[str, np.ndarray]
    run: RunData

    @property
    def length(self) -> np.ndarray:
        return self.out["length_mm"]

    @property
    def resistance(self) -> np.ndarray:
        return self.out["resistance_ohm"]


def run_data(name: str, hist: dict[str, np.ndarray], out: dict[str, np.ndarray]) -> RunData:
    """Contract columns of a simulated history as an in-memory RunData (no file)."""
    n = len(hist["t"])
    samples = {"t": hist["t"], "turns": hist["turns"], "length": out["length_mm"], "resistance": out["resistance_ohm"],
               "heater_voltage": hist["heater_voltage"], "load": hist["load_g"] * NEWTON_PER_GRAM,
               "segment": hist["segment"], "motor_moving": hist["motor_moving"],
               "counter": np.arange(n, dtype=np.uint32)}
    units = {"t": "s", "turns": "turn", "length": "mm", "resistance": "ohm", "heater_voltage": "V", "load": "N",
             "segment": "1", "motor_moving": "1", "counter": "1"}
    return RunData(f"<sim:{name}>", {"format": "tsa-bench/run", "exit_status": "success"}, samples, units)


def plateaus(hist: dict[str, np.ndarray], values: np.ndarray, fraction: float = 1 / 3) -> list[tuple[int, float]]:
    """(segment, mean of ``values`` over the last ``fraction`` of it) for every stopped segment, in order."""
    seg, moving = hist["segment"], hist["motor_moving"].astype(bool)
    out = []
    for s in np.unique(seg):
        idx = np.flatnonzero((seg == s) & ~moving)
        if len(idx) < 3:
            continue
        tail = idx[int(len(idx) * (1 - fraction)):]
        out.append((int(s), float(np.nanmean(values[tail]))))
    return out


class Lab:
    """Simulates and caches the thesis experiments on a set of preset plants (module contract)."""

    def __init__(self, plants: dict[str, dict[str, Any]] | None = None, seed: int = 0, quick: bool = False,
                 bench_dir: Path = BENCH_DIR, manipulator: dict[str, Any] | None = None) -> None:
        self.plants = {p: preset_plant(p, bench_dir) for p in PRESETS}
        if plants:
            self.plants.update(plants)
        #: the soft manipulator's settings (None: configs/manipulator/thesis.yaml)
        self.manipulator = manipulator
        self.seed = seed
        self.quick = quick
        self._cache: dict[Any, Any] = {}

    # -- plumbing --------------------------------------------------------
    def _seed(self, name: str) -> int:
        return (self.seed * 1_000_003 + zlib.crc32(name.encode())) % (2 ** 31)

    def simulate(self, name: str, preset: str, hist: dict[str, np.ndarray], settle_s: float = 600.0,
                 quiet: bool = False) -> SimRun:
        """Run ``hist`` on ``preset`` after ``settle_s`` at its first input (the mass hangs before the test)."""
        key = ("run", name, quiet)
        if key in self._cache:
            return self._cache[key]
        cfg = dict(self.plants[preset])
        if quiet:
            effects = {k: dict(v or {}) for k, v in dict(cfg.get("effects") or {}).items()}
            for e in ("sensor_noise", "quantisation"):
                effects[e] = {**effects.get(e, {}), "enabled": False}
            cfg["effects"] = effects
        plant = plant_from_config(cfg, seed=self._seed(name))
        if settle_s > 0:
            ts = np.arange(0.0, settle_s, 1.0)
            simulate(plant, ts, hist["turns"][0], hist["heater_voltage"][0], hist["load_g"][0], np.zeros(len(ts), bool))
        out = simulate(plant, hist["t"] + settle_s, hist["turns"], hist["heater_voltage"], hist["load_g"],
                       hist["motor_moving"].astype(bool))
        sim = SimRun(name, hist, out, run_data(name, hist, out))
        self._cache[key] = sim
        return sim

    def cached(self, key: Any, make) -> Any:
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    # -- the experiments -------------------------------------------------
    def sweep(self, ply: int, load_g: float) -> SimRun:
        full, step = FULL_TWIST[ply]
        n = int(round(full / step))
        up = [step * i for i in range(1, n + 1)]
        steps: list[tuple] = [("hold", 10.0)]
        for x in up + up[-2::-1] + [0.0]:
            steps += [("move", x), ("hold", 5.0)]
        h = history(steps, dt_s=0.1, load_g=load_g)
        return self.simulate(f"sweep-{ply}ply-{load_g:g}g", PRESET_FOR[f"ply{ply}"], h)

    def heat(self, ply: int, load_g: float) -> SimRun:
        full, _ = FULL_TWIST[ply]
        h = history(twist_heat_steps(full, max_V=MAX_VOLTAGE_V, hold_s=30.0 if self.quick else 90.0), dt_s=0.5,
                    load_g=load_g)
        return self.simulate(f"heat-{ply}ply-{load_g:g}g", PRESET_FOR[f"ply{ply}"], h)

    def scheme(self, scheme: int, load_g: float) -> SimRun:
        levels = [20.0, 25.0, 30.0, 35.0, 40.0, 45.0, 50.0, 55.0, 50.0, 45.0, 40.0, 35.0, 30.0, 25.0, 20.0]
        hold = 60.0 if self.quick else 180.0
        steps: list[tuple] = [("hold", 60.0)]
        for x in levels:
            steps += [("move", x), ("hold", hold)]
        h = history(steps, dt_s=0.5, load_g=load_g)
        return self.simulate(f"scheme{scheme}-{load_g:g}g", PRESET_FOR[f"scheme{scheme}"], h)

    def steps(self, duration_s: float) -> SimRun:
        cycles = 1 if self.quick else 2
        h = history(step_duration_steps(duration_s, cycles=cycles), dt_s=0.05 if duration_s < 3 else 0.1,
                    load_g=350.0)
        return self.simulate(f"steps-{duration_s:g}s", PRESET_FOR["transient"], h)

    def stiffness(self, ply: int) -> SimRun:
        top = LOADS[ply][-1]
        loads = list(np.arange(0.0, top + 1, 50.0))
        seq = loads + loads[-2::-1]
        t, lo = [], []
        for i, m in enumerate(seq):
            for k in range(600):
                t.append((i * 600 + k) * 0.1)
                lo.append(m)
        n = len(t)
        h = {"t": np.array(t), "turns": np.zeros(n), "heater_voltage": np.zeros(n), "load_g": np.array(lo),
             "motor_moving": np.zeros(n, np.uint8), "segment": np.repeat(np.arange(len(seq)), 600).astype(np.int32)}
        return self.simulate(f"stiffness-{ply}ply", PRESET_FOR[f"ply{ply}"], h, settle_s=60.0)

    def lifetime(self) -> SimRun:
        h = history(lifetime_steps(60 if self.quick else LIFETIME_CYCLES), dt_s=0.2, load_g=550.0)
        return self.simulate("lifetime", PRESET_FOR["transient"], h, settle_s=0.0)

    def thermal(self, ply: int, load_g: float) -> SimRun:
        full, _ = FULL_TWIST[ply]
        steps: list[tuple] = [("hold", 5.0), ("move", full), ("hold", 60.0), ("heater", MAX_VOLTAGE_V, 60.0),
                              ("heater", 0.0, 400.0)]
        h = history(steps, dt_s=0.1, load_g=load_g)
        return self.simulate(f"thermal-{ply}ply-{load_g:g}g", PRESET_FOR[f"ply{ply}"], h, quiet=True)

    def transient_quiet(self) -> SimRun:
        steps: list[tuple] = [("hold", 5.0), ("move", 15.0), ("hold", 200.0), ("move", 17.0), ("hold", 200.0)]
        h = history(steps, dt_s=0.1, load_g=350.0)
        return self.simulate("transient-quiet", PRESET_FOR["transient"], h, quiet=True)
