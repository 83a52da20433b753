"""Free parameters of the judged model, with search ranges and weak priors; plant-config access.

Units: every bound is in the parameter's own units (``tsa-bench effects``).

Contract: a :class:`ParamSpec` maps one plant-config entry (``"geometry.<key>"`` for the
plant's top-level keys, ``"<effect>.<param>"`` otherwise) to an optimiser variable ``u``
in [0, 1], linearly or logarithmically between ``lo`` and ``hi``. ``hard_lo``/``hard_hi``
mark bounds that are physical limits (a non-negative coefficient at 0); ending at any
other bound means the data want a value outside the plausible range, which the engine
reports. ``prior`` sets a weak Gaussian prior around the model's own value: its standard
deviation in log units for log parameters (a factor of 10), and for linear ones the larger
of ``prior`` and the value itself (a factor-of-two belief). It only decides directions the
data leave flat (untwisted length and stiffness from a single load; a wear rate that one
twist and untwist cannot tell from the contact term). The ranges cover
the thesis's strings (3- to 8-ply, Scheme 1 and 2, 3-12 ohm, 150-400 mm) with margin.
:func:`baseline_specs` lists the calibrated parameters of whatever a model enables.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from typing import Any

from tsa_bench.analysis.paramspec import ParamSpec
from tsa_bench.sim.effects import EFFECTS, FORMS, effect_class

#: Effects never judged as causes (measurement, not physics).
SENSOR_EFFECTS = ("sensor_noise", "quantisation")
LN10 = math.log(10.0)


#: The judged model's own parameters (always calibrated when the effect is on).
BASE_SPECS: dict[str, ParamSpec] = {s.key: s for s in (
    ParamSpec("geometry.untwisted_length_mm", 40.0, 2000.0, True, prior=LN10),
    ParamSpec("geometry.radius_mm", 0.01, 10.0, True, prior=LN10),
    ParamSpec("geometry.resistance_ohm", 0.05, 500.0, True, prior=LN10),
    ParamSpec("string_compliance.stiffness_N", 0.5, 1e5, True, hard_hi=True, prior=LN10),  # 1e5 N: inextensible
    ParamSpec("thermal_contraction.strain_per_K", 0.0, 0.02, hard_lo=True, prior=5e-4),
    ParamSpec("resistance_length.ohm_per_mm", -1.0, 1.0, prior=0.005),
    ParamSpec("resistance_length.contact_ohm_per_turn", -0.2, 0.2, prior=5e-4),
)}


def enabled_effects(plant_cfg: Mapping[str, Any]) -> list[str]:
    """Effects the plant config switches on: library effects (omitted ones take ``default_enabled``)
    and alternative forms (only when named)."""
    items = plant_cfg.get("effects") or {}
    out = []
    for name in list(EFFECTS) + list(FORMS):
        if name in FORMS and name not in items:
            continue
        cfg = items.get(name, {})
        default = effect_class(name).default_enabled
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
    return float(getattr(effect_class(head).Params(), name))


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
    """Calibrated parameters of a model: geometry plus its enabled effects' free parameters,
    each range widened to contain the model's own value."""
    from tsa_bench.analysis.families import FORM_SPECS

    on = enabled_effects(plant_cfg)   # a list in library order: the parameter vector's order must not hang on str hashing
    specs: list[ParamSpec] = []
    for key, spec in BASE_SPECS.items():
        head = key.split(".")[0]
        if head != "geometry" and head not in on:
            continue
        specs.append(spec.with_range(get_value(plant_cfg, key)))
    for name in on:
        for s in FORM_SPECS.get(name, ()):
            # a weak prior around the judged model's own value (used where it gives a centre)
            prior = LN10 if s.log else (s.hi - s.lo) / 200.0
            specs.append(ParamSpec(s.key, s.lo, s.hi, s.log, s.hard_lo, s.hard_hi, prior).with_range(
                get_value(plant_cfg, s.key)))
    return specs
