"""The plant a point simulates: its bench preset's plant with the point's overrides.

Contract: :func:`resolved_plant` deep-merges ``config["plant"]`` (dotted overrides, e.g.
``effects.resistance_creep.ohm_per_turn``) into the ``plant`` mapping of
``configs/bench/<bench.preset>.yaml`` and, for diagnose points, hides ``effect`` in it
(:mod:`tsa_bench.sweep.effects`). Reproduce points have no plant of their own (None).
"""

from __future__ import annotations

import copy
from functools import lru_cache
from typing import Any

from tsa_bench.sweep.effects import hide


@lru_cache(maxsize=32)
def _preset(name: str) -> dict[str, Any]:
    from tsa_bench.reproduce.runs import preset_plant

    return preset_plant(name)


def merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``over`` written in, recursively (neither is changed)."""
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def resolved_plant(runner: str, config: dict[str, Any]) -> dict[str, Any] | None:
    """The plant mapping a point simulates (module contract)."""
    if runner == "reproduce":
        return None
    plant = merge(_preset(config["bench"]["preset"]), config.get("plant") or {})
    if runner == "diagnose":
        plant = hide(plant, config["effect"]["name"], float(config["effect"]["magnitude"]))
    return plant
