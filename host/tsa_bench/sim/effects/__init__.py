"""Named, documented, switchable physical effects of the simulated plant.

Units: see :mod:`tsa_bench.sim.effects.base` (s, turns, V, g/N, mm, ohm, degC).

Contract: importing this package registers every effect in :data:`EFFECTS` and every
alternative form of one (:data:`FORMS`, off unless a plant config names it); the plant
runs the enabled ones in canonical stage order (:func:`canonical_order`), whatever the
config order. :func:`describe_effects` lists them for ``tsa-bench effects``.
"""

from __future__ import annotations

from typing import Any

from tsa_bench.sim.effects.base import (EFFECTS, FORMS, STAGES, Effect, PlantState, build_effect, canonical_order,
                                        check_keys, describe_effect, effect_class, number_param, parse_effect_config,
                                        param, register_effect, register_form)
# registration order = module order within a stage; coupling first, so that twist
# stiffening sets its stiffness factor before load_dependence and string_compliance
from tsa_bench.sim.effects import coupling as _coupling  # noqa: F401
from tsa_bench.sim.effects import motor as _motor  # noqa: F401
from tsa_bench.sim.effects import thermal as _thermal  # noqa: F401
from tsa_bench.sim.effects import mechanics as _mechanics  # noqa: F401
from tsa_bench.sim.effects import resistance as _resistance  # noqa: F401
from tsa_bench.sim.effects import variability as _variability  # noqa: F401
from tsa_bench.sim.effects import sensing as _sensing  # noqa: F401
# sensor drifts last: a plant that does not name them draws the random numbers it always drew
from tsa_bench.sim.effects import drift as _drift  # noqa: F401
from tsa_bench.sim.effects import forms_motor as _forms_motor  # noqa: F401  (alternative forms, off by default)
from tsa_bench.sim.effects import forms_mechanics as _forms_mechanics  # noqa: F401
from tsa_bench.sim.effects import forms_resistance as _forms_resistance  # noqa: F401
from tsa_bench.sim.effects.mechanics import tsa_length_mm
from tsa_bench.sim.effects.sensing import Quantisation, SensorNoise

__all__ = ["EFFECTS", "FORMS", "effect_class", "register_form", "describe_forms", "STAGES", "Effect", "PlantState",
           "register_effect", "canonical_order", "build_effect", "parse_effect_config", "describe_effects", "check_keys", "number_param", "param", "tsa_length_mm",
           "SensorNoise", "Quantisation"]


def describe_effects() -> list[dict[str, Any]]:
    """Every registered effect in canonical order: name, stage, source, doc (first line),
    params (name, units, default, doc)."""
    return [describe_effect(EFFECTS[name]) for name in canonical_order()]


def describe_forms() -> list[dict[str, Any]]:
    """Every alternative form: as :func:`describe_effects` plus ``form_of`` and ``form``."""
    return [{**describe_effect(FORMS[name]), "form_of": FORMS[name].form_of, "form": FORMS[name].form}
            for name in canonical_order(list(FORMS))]
