"""What a study point's configuration may hold: the parameter tree per runner.

A point's configuration is a nested mapping of sections (``protocol``, ``bench``,
``plant``, and the runner's own: ``effect``/``diagnose``, ``fit``, ``detect``,
``reproduce``). :func:`defaults` gives the tree a runner starts from; every key a study
sets (in ``base``) or varies (in ``vary``) must be a leaf of that tree or of the plant
tree (:func:`plant_leaf`), or the study is refused before anything runs.

Units are in the names (``hold_s``, ``load_g``, ``lo_turns``); plant parameters carry
the units of ``tsa-bench effects``.
"""

from __future__ import annotations

import copy
import dataclasses
from typing import Any

RUNNERS = ("simulate", "diagnose", "fit", "reproduce")

#: Protocol shapes and their parameters (defaults). ``staircase`` is the thesis's
#: step-duration staircase (section 2.5.2), ``lifetime`` its cycling test (2.5.2),
#: ``diagnostic`` a rich run for diagnose (staircases, fast cycles, a load step, heater steps).
SHAPES: dict[str, dict[str, Any]] = {
    "staircase": {"hold_s": 6.0, "cycles": 2, "lo_turns": 15.0, "hi_turns": 25.0, "step_turns": 2.0,
                  "rest_s": 120.0, "load_g": 350.0, "dt_s": 0.1},
    "lifetime": {"cycles": 50, "load_g": 550.0, "dt_s": 0.1},
    "diagnostic": {"repeats": 2, "hold_s": 60.0, "cycles": 5, "load_g": 500.0, "dt_s": 0.1},
}

_BENCH = {"preset": "sim", "seed": 0, "settle_s": 1200.0}

_RUNNER_SECTIONS: dict[str, dict[str, Any]] = {
    "simulate": {"detect": {"z_threshold": 3.0}},
    "diagnose": {"effect": {"name": "none", "magnitude": 1.0},
                 "diagnose": {"model": "sim-baseline", "max_causes": 1, "seed": 0}},
    "fit": {"fit": {"model": "preisach", "levels": 20, "validate_hold_s": 32.0, "validate_cycles": 2}},
    "reproduce": {"reproduce": {"record": "", "quick": True, "seed": 0}},
}
_DEFAULT_SHAPE = {"simulate": "lifetime", "diagnose": "diagnostic", "fit": "staircase"}
_DEFAULT_PRESET = {"diagnose": "sim-baseline"}

#: Choices of text parameters (checked for base and varied values alike).
CHOICES: dict[str, tuple[str, ...]] = {
    "protocol.shape": tuple(SHAPES),
    "fit.model": ("preisach", "polynomial", "strain-resistance", "self-sensing"),
}


def defaults(runner: str, shape: str | None = None) -> dict[str, Any]:
    """The configuration tree a ``runner`` point starts from (``shape``: the protocol shape)."""
    tree: dict[str, Any] = copy.deepcopy(_RUNNER_SECTIONS[runner])
    if runner != "reproduce":
        s = shape or _DEFAULT_SHAPE[runner]
        tree["protocol"] = {"shape": s, **SHAPES[s]}
        tree["bench"] = {**_BENCH, "preset": _DEFAULT_PRESET.get(runner, _BENCH["preset"])}
        tree["plant"] = {}
    return tree


def plant_leaf(parts: list[str]) -> Any:
    """The default of the plant parameter ``plant.<parts>``; KeyError naming what is unknown."""
    from tsa_bench.sim.effects.base import EFFECTS, FORMS, effect_class
    from tsa_bench.sim.plant import PLANT_KEYS

    if not parts:
        raise KeyError("plant: name a parameter (plant.radius_mm, plant.effects.<effect>.<parameter>)")
    head = parts[0]
    if head != "effects":
        if head not in PLANT_KEYS or len(parts) != 1:
            raise KeyError(f"unknown plant parameter {'.'.join(parts)!r} (known: "
                           f"{', '.join(k for k in PLANT_KEYS if k != 'effects')}, effects.<effect>.<parameter>)")
        return 0 if head == "seed" else 0.0
    if len(parts) != 3:
        raise KeyError("plant.effects: write plant.effects.<effect>.<parameter> (or .enabled)")
    cls = effect_class(parts[1])
    if cls is None:
        raise KeyError(f"unknown plant effect {parts[1]!r} (known: {', '.join(sorted(EFFECTS))}; forms: "
                       f"{', '.join(sorted(FORMS))})")
    fields = {f.name: f for f in dataclasses.fields(cls.Params)}
    if parts[2] == "enabled":
        return True
    if parts[2] not in fields:
        raise KeyError(f"effect {parts[1]!r} has no parameter {parts[2]!r} (known: enabled, "
                       f"{', '.join(fields)})")
    return fields[parts[2]].default


def leaf_default(tree: dict[str, Any], path: str) -> Any:
    """The default of dotted ``path`` in ``tree`` (plant paths via :func:`plant_leaf`); KeyError if unknown."""
    parts = path.split(".")
    if parts[0] == "plant" and "plant" in tree:
        return plant_leaf(parts[1:])
    node: Any = tree
    for i, p in enumerate(parts):
        if not isinstance(node, dict) or p not in node:
            known = ", ".join(sorted(node)) if isinstance(node, dict) else "nothing (a value, not a section)"
            where = ".".join(parts[:i]) or "the point"
            raise KeyError(f"unknown parameter {path!r}: {where} has no {p!r} (known: {known})")
        node = node[p]
    if isinstance(node, dict):
        raise KeyError(f"{path!r} is a section; name one of its parameters ({', '.join(sorted(node))})")
    return node


def check_value(path: str, default: Any, value: Any) -> str | None:
    """Why ``value`` cannot stand for a parameter whose default is ``default``, or None."""
    if path in CHOICES and value not in CHOICES[path]:
        return f"{path} must be one of {', '.join(CHOICES[path])}, got {value!r}"
    if isinstance(default, bool):
        return None if isinstance(value, bool) else f"{path} takes true or false, got {value!r}"
    if isinstance(default, int):
        return None if isinstance(value, int) and not isinstance(value, bool) else \
            f"{path} takes an integer, got {value!r}"
    if isinstance(default, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        return None if ok else f"{path} takes a number, got {value!r}"
    if isinstance(default, str):
        return None if isinstance(value, str) else f"{path} takes text, got {value!r}"
    return None


def set_path(cfg: dict[str, Any], path: str, value: Any) -> None:
    """Write ``value`` at dotted ``path`` of ``cfg``, creating sections as needed."""
    parts = path.split(".")
    node = cfg
    for p in parts[:-1]:
        node = node.setdefault(p, {})
    node[parts[-1]] = value
