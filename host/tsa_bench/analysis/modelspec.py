"""Free parameters of the judged model and of each candidate effect, with physical bounds.

Units: every bound is in the parameter's own units (``tsa-bench effects``).

Contract: a :class:`ParamSpec` maps one plant-config entry (``"geometry.<key>"`` for
the plant's top-level keys, ``"<effect>.<param>"`` otherwise) to an optimiser variable
``u`` in [0, 1], linearly or logarithmically between ``lo`` and ``hi``.
:func:`baseline_specs` lists the calibrated parameters of whatever effects a model
enables (geometry always); :data:`CANDIDATE_SPECS` the parameters freed when a
candidate effect is switched on; :data:`SCREEN_VARIANTS` a few parameter sets per
candidate used to compute its signature (an effect whose default does not show on the
data, e.g. missed steps at 0.4 N m, still gets a fair screen).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from tsa_bench.sim.effects import EFFECTS

#: Effects never judged as causes (measurement, not physics).
SENSOR_EFFECTS = ("sensor_noise", "quantisation")


@dataclass(frozen=True)
class ParamSpec:
    key: str          # "geometry.radius_mm" or "effect.param"
    lo: float
    hi: float
    log: bool = False

    def to_value(self, u: float) -> float:
        u = min(1.0, max(0.0, float(u)))
        if self.log:
            return math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo)))
        return self.lo + u * (self.hi - self.lo)

    def to_u(self, value: float) -> float:
        if self.log:
            v = min(self.hi, max(self.lo, value))
            return (math.log(v) - math.log(self.lo)) / (math.log(self.hi) - math.log(self.lo))
        return min(1.0, max(0.0, (value - self.lo) / (self.hi - self.lo)))


# relative bounds (x value in the model) for the baseline's calibrated parameters
_REL = {
    "geometry.untwisted_length_mm": (0.9, 1.1, False),
    "geometry.radius_mm": (0.5, 2.0, True),
    "geometry.resistance_ohm": (0.8, 1.25, False),
    "string_compliance.stiffness_N": (0.3, 3.0, True),
    "thermal_contraction.strain_per_K": (0.5, 2.0, False),
}
# absolute bounds, for parameters that may sensibly cross zero or be zero
_ABS = {
    "resistance_length.ohm_per_mm": (-0.05, 0.1, False),
    "resistance_length.contact_ohm_per_turn": (-0.01, 0.01, False),
}

#: Parameters freed when a candidate effect is switched on (absolute physical bounds).
CANDIDATE_SPECS: dict[str, tuple[ParamSpec, ...]] = {
    "missed_steps": (ParamSpec("missed_steps.holding_torque_Nm", 1e-4, 0.5, True),),
    "thermal_dynamics": (ParamSpec("thermal_dynamics.thermal_resistance_K_per_W", 0.5, 30.0, True),
                         ParamSpec("thermal_dynamics.heat_capacity_J_per_K", 0.03, 3.0, True),
                         ParamSpec("thermal_dynamics.cooling_time_constant_s", 3.0, 300.0, True)),
    "load_dependence": (ParamSpec("load_dependence.stiffness_softening", 0.0, 1.5),),
    "twist_hysteresis": (ParamSpec("twist_hysteresis.play_turns", 0.0, 3.0),),
    "length_creep": (ParamSpec("length_creep.strain_per_N", 0.0, 0.006),
                     ParamSpec("length_creep.time_constant_s", 10.0, 2000.0, True)),
    "resistance_hysteresis": (ParamSpec("resistance_hysteresis.ohm_per_mm", 0.0, 0.08),
                              ParamSpec("resistance_hysteresis.alpha_mm", 0.1, 6.0, True)),
    "resistance_transient_decay": (ParamSpec("resistance_transient_decay.b1_ohm", -0.01, 0.002),
                                   ParamSpec("resistance_transient_decay.b2_ohm", -0.15, 0.02)),
    "resistance_creep": (ParamSpec("resistance_creep.ohm_per_turn", 0.0, 2e-4),),
    "resistance_temperature": (ParamSpec("resistance_temperature.alpha_per_K", -2e-3, 4e-3),),
}

#: Parameter sets used for screening signatures (besides the effect's defaults).
SCREEN_VARIANTS: dict[str, tuple[dict[str, float], ...]] = {
    "missed_steps": ({"holding_torque_Nm": 5e-4}, {"holding_torque_Nm": 1e-3}, {"holding_torque_Nm": 2e-3},
                     {"holding_torque_Nm": 4e-3}),
    "thermal_dynamics": ({}, {"cooling_time_constant_s": 8.0}, {"cooling_time_constant_s": 100.0}),
    "load_dependence": ({},),
    "twist_hysteresis": ({}, {"play_turns": 1.0}),
    "length_creep": ({}, {"time_constant_s": 40.0}, {"time_constant_s": 700.0}),
    "resistance_hysteresis": ({}, {"alpha_mm": 3.0}),
    "resistance_transient_decay": ({},),
    "resistance_creep": ({},),
    "resistance_temperature": ({},),
}


def candidate_effects(plant_cfg: Mapping[str, Any]) -> list[str]:
    """Library effects the model leaves off (sensor effects excluded)."""
    on = enabled_effects(plant_cfg)
    return [n for n in EFFECTS if n not in on and n not in SENSOR_EFFECTS and n in CANDIDATE_SPECS]


def enabled_effects(plant_cfg: Mapping[str, Any]) -> list[str]:
    """Names of the effects the plant config switches on (omitted effects take ``default_enabled``)."""
    items = plant_cfg.get("effects") or {}
    out = []
    for name in EFFECTS:
        cfg = items.get(name, {})
        default = EFFECTS[name].default_enabled
        if isinstance(cfg, bool):
            on = cfg
        elif cfg is None:
            on = default
        else:
            on = bool(cfg.get("enabled", default))
        if on:
            out.append(name)
    return out


def get_value(plant_cfg: Mapping[str, Any], key: str) -> float:
    """Value of ``geometry.x`` / ``effect.param`` in a plant config (defaults filled in)."""
    head, name = key.split(".", 1)
    if head == "geometry":
        defaults = {"untwisted_length_mm": 248.0, "radius_mm": 0.51, "resistance_ohm": 5.0}
        return float(plant_cfg.get(name, defaults[name]))
    cfg = (plant_cfg.get("effects") or {}).get(head) or {}
    if isinstance(cfg, Mapping) and name in cfg:
        return float(cfg[name])
    return float(getattr(EFFECTS[head].Params(), name))


def set_values(plant_cfg: Mapping[str, Any], values: Mapping[str, float]) -> dict:
    """A deep copy of the plant config with ``values`` written in."""
    cfg = copy.deepcopy(dict(plant_cfg))
    cfg["effects"] = {k: (dict(v) if isinstance(v, Mapping) else ({"enabled": v} if isinstance(v, bool) else {}))
                      for k, v in (cfg.get("effects") or {}).items()}
    for key, value in values.items():
        head, name = key.split(".", 1)
        if head == "geometry":
            cfg[name] = float(value)
        else:
            cfg["effects"].setdefault(head, {})[name] = float(value)
    return cfg


def switch(plant_cfg: Mapping[str, Any], name: str, on: bool, params: Mapping[str, float] | None = None) -> dict:
    """Copy with effect ``name`` switched on/off (``params`` written in)."""
    cfg = set_values(plant_cfg, {f"{name}.{k}": v for k, v in (params or {}).items()})
    cfg["effects"].setdefault(name, {})["enabled"] = bool(on)
    return cfg


def baseline_specs(plant_cfg: Mapping[str, Any]) -> list[ParamSpec]:
    """Calibrated parameters of the model: geometry plus its enabled effects' free parameters."""
    on = set(enabled_effects(plant_cfg))
    specs: list[ParamSpec] = []
    for key, (a, b, log) in _REL.items():
        head = key.split(".")[0]
        if head != "geometry" and head not in on:
            continue
        v = get_value(plant_cfg, key)
        if v <= 0:
            continue
        specs.append(ParamSpec(key, a * v, b * v, log))
    for key, (a, b, log) in _ABS.items():
        if key.split(".")[0] in on:
            v = get_value(plant_cfg, key)
            specs.append(ParamSpec(key, min(a, v), max(b, v), log))
    for name in on:
        for s in CANDIDATE_SPECS.get(name, ()):
            v = get_value(plant_cfg, s.key)
            specs.append(ParamSpec(s.key, min(s.lo, v), max(s.hi, v), s.log))
    return specs
