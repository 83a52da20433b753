"""The plant the fitting tests generate their runs on: the `sim` preset with its transient-resistance
levels pinned.

The thesis calibration (scripts/calibrate_presets.py) re-fits configs/bench/sim.yaml's resistance
levels and hold-to-hold scatter to the thesis's errors; a test of a fitting method checks the
method on one generated run and must not change verdict when that calibration moves. The values
are those the tests were written against (the presets of e097870). Units: ohm, ohm/mm.
"""

from __future__ import annotations

from typing import Any

from tsa_bench.reproduce.runs import preset_plant

PINNED = {"resistance_ohm": 4.76376,
          ("resistance_length", "ohm_per_mm"): 0.0296407,
          ("resistance_settling", "hold_sd_ohm"): 0.00881707,
          ("resistance_settling", "run_sd_ohm"): 0.0195736}


def generator_plant() -> dict[str, Any]:
    """The `sim` preset's plant mapping with :data:`PINNED` values."""
    plant = preset_plant("sim")
    for key, value in PINNED.items():
        if isinstance(key, tuple):
            plant["effects"][key[0]][key[1]] = value
        else:
            plant[key] = value
    return plant
