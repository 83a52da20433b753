"""Hidden effects of diagnose-power points: reference strengths scaled by a magnitude.

A diagnose point hides ``effect.name`` in the judged model's plant with its strength
parameters at ``magnitude`` times the reference below (magnitude 1 is a mid-range value
of the physical ranges the diagnose tests draw from) and the shape parameters fixed;
magnitude 0 (or name ``none``) is a clean run. Units are those of ``tsa-bench effects``.
"""

from __future__ import annotations

from typing import Any

#: effect -> (strength parameters scaled by the magnitude, shape parameters kept)
REFERENCE: dict[str, tuple[dict[str, float], dict[str, float]]] = {
    "resistance_creep": ({"ohm_per_turn": 1.5e-5}, {}),
    "resistance_transient_decay": ({"b1_ohm": -1.71e-3, "b2_ohm": -2.68e-2}, {}),
    "resistance_hysteresis": ({"ohm_per_mm": 0.015}, {"alpha_mm": 1.0}),
    "length_creep": ({"strain_per_N": 1e-3}, {"time_constant_s": 180.0}),
    "load_dependence": ({"stiffness_softening": 0.3}, {}),
    "twist_hysteresis": ({"play_turns": 0.3}, {}),
}
NAMES = ("none", *REFERENCE)


def hide(plant: dict[str, Any], name: str, magnitude: float) -> dict[str, Any]:
    """Copy of ``plant`` with effect ``name`` on at ``magnitude`` x its reference (``none``/0: unchanged)."""
    if name == "none" or magnitude == 0:
        return plant
    scaled, fixed = REFERENCE[name]
    out = {**plant, "effects": dict(plant.get("effects") or {})}
    params = {k: v * magnitude for k, v in scaled.items()}
    out["effects"][name] = {**dict(out["effects"].get(name) or {}), "enabled": True, **fixed, **params}
    return out
