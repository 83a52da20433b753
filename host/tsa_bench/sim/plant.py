"""The simulated plant: what a pair of twisted SCP strings does under a hanging load.

Units: time in s, twist in motor turns (signed), heater voltage in V, load in g,
length in mm, resistance in ohm.

Contract: a :class:`Plant` is told the hanging mass (``set_load``) and sampled with
nondecreasing times; each sample returns the length and resistance the transducers
see. :class:`TsaPlant` computes the quasi-static TSA length of
:mod:`tsa_bench.sim.kinematics` (compliant strings, radius growth, clamped at full
twist), a resistance that rises linearly with length, ``R = R0 + dR/dX (X - L0)``
(never below zero), and then applies its named effects (:mod:`tsa_bench.sim.effects`)
in order; the shipped bench adds only sensor noise. The heater and motor state are
passed through to the effects (the quasi-static model ignores them). ``sample`` costs
a few microseconds.
"""

from __future__ import annotations

import random
from collections.abc import Mapping, Sequence
from typing import Any, Protocol

from tsa_bench.sim.effects import EFFECTS, PlantEffect, PlantInputs, check_keys, number_param
from tsa_bench.sim.kinematics import TsaGeometry, contracted_length_mm
from tsa_bench.sim.readings import PlantReading

__all__ = ["Plant", "PlantReading", "PlantInputs", "TsaPlant", "plant_from_config", "PLANT_KEYS"]

#: Keys accepted in a bench file's ``plant`` mapping.
PLANT_KEYS = ("untwisted_length_mm", "radius_mm", "stiffness_N", "resistance_ohm", "resistance_per_mm_ohm",
              "initial_load_g", "seed", "effects")


class Plant(Protocol):
    """What the simulated device drives and measures."""

    def set_load(self, load_g: float) -> None:
        """Change the hanging mass (g)."""

    def sample(self, t_s: float, turns: float, heater_voltage_V: float, motor_moving: bool) -> PlantReading:
        """The reading at time ``t_s`` (nondecreasing between calls)."""


class TsaPlant:
    """Quasi-static compliant TSA plus a chain of effects (see module docstring)."""

    def __init__(self, geometry: TsaGeometry, resistance_ohm: float, resistance_per_mm_ohm: float,
                 load_g: float = 0.0, effects: Sequence[PlantEffect] = ()) -> None:
        self.geometry = geometry
        self.resistance_ohm = resistance_ohm
        self.resistance_per_mm_ohm = resistance_per_mm_ohm
        self.effects = tuple(effects)
        self._c_per_turn2 = geometry.twist_coefficient_mm3_per_turn2
        self._r_at_zero_mm = resistance_ohm - resistance_per_mm_ohm * geometry.untwisted_length_mm
        self.load_g = 0.0
        self._stretched_mm = geometry.untwisted_length_mm
        self.set_load(load_g)

    def set_load(self, load_g: float) -> None:
        if not load_g >= 0:
            raise ValueError(f"load_g must be >= 0, got {load_g}")
        self.load_g = float(load_g)
        self._stretched_mm = self.geometry.stretched_length_mm(self.load_g)

    def quasi_static(self, turns: float) -> PlantReading:
        """Length and resistance without effects, at the current load."""
        x = contracted_length_mm(self._stretched_mm, self._c_per_turn2 * turns * turns)
        return PlantReading(x, max(0.0, self._r_at_zero_mm + self.resistance_per_mm_ohm * x))

    def sample(self, t_s: float, turns: float, heater_voltage_V: float, motor_moving: bool) -> PlantReading:
        reading = self.quasi_static(turns)
        if self.effects:
            inputs = PlantInputs(t_s, turns, heater_voltage_V, motor_moving, self.load_g)
            for effect in self.effects:
                reading = effect.apply(inputs, reading)
        return reading


def _effects_from_config(items: Any, rng: random.Random) -> list[PlantEffect]:
    if items is None:
        return []
    if not isinstance(items, list):
        raise ValueError("plant: 'effects' must be a list of mappings, each with a 'name'")
    effects: list[PlantEffect] = []
    for i, item in enumerate(items):
        if not isinstance(item, Mapping) or not isinstance(item.get("name"), str):
            raise ValueError(f"plant.effects[{i}]: must be a mapping with a 'name' key, got {item!r}")
        factory = EFFECTS.get(item["name"])
        if factory is None:
            raise ValueError(f"plant.effects[{i}]: unknown effect '{item['name']}' "
                             f"(known: {', '.join(sorted(EFFECTS))})")
        params = {k: v for k, v in item.items() if k != "name"}
        effects.append(factory(params, random.Random(rng.getrandbits(64))))
    return effects


def plant_from_config(plant_cfg: Mapping[str, Any], seed: int | None = None) -> TsaPlant:
    """Build the plant from a bench file's ``plant`` mapping; raise ValueError naming a bad key.

    ``seed`` overrides ``plant_cfg['seed']``; with neither, noise is not reproducible.
    Missing keys take the shipped simulated bench's values (see configs/bench/sim.yaml).
    """
    where = "plant"
    check_keys(plant_cfg, PLANT_KEYS, where)
    geometry = TsaGeometry(
        untwisted_length_mm=number_param(plant_cfg, "untwisted_length_mm", where, 248.0, minimum=1e-9),
        radius_mm=number_param(plant_cfg, "radius_mm", where, 0.51, minimum=0.0),
        stiffness_N=number_param(plant_cfg, "stiffness_N", where, 31.88, minimum=1e-9),
    )
    if seed is None:
        cfg_seed = plant_cfg.get("seed")
        if cfg_seed is not None and (isinstance(cfg_seed, bool) or not isinstance(cfg_seed, int)):
            raise ValueError(f"{where}: 'seed' must be an integer or null, got {cfg_seed!r}")
        seed = cfg_seed
    rng = random.Random(seed)
    return TsaPlant(
        geometry,
        resistance_ohm=number_param(plant_cfg, "resistance_ohm", where, 5.0, minimum=0.0),
        resistance_per_mm_ohm=number_param(plant_cfg, "resistance_per_mm_ohm", where, 0.015),
        load_g=number_param(plant_cfg, "initial_load_g", where, 0.0, minimum=0.0),
        effects=_effects_from_config(plant_cfg.get("effects"), rng),
    )
