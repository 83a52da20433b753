"""The diagnose runner: simulate a run with an effect hidden, diagnose it against a model.

Figures: ``verdict`` and ``causes`` (as diagnose gives them), ``alarm`` (the verdict is
not ``explained``: on a clean point a false alarm), ``detected`` (the hidden effect is
named first; empty on a clean point), ``run_length_min``, ``samples`` and
``diagnose_s`` (wall time of the diagnosis).
"""

from __future__ import annotations

import time
from typing import Any

from tsa_bench.sweep.points.common import run_data, simulate_point


def run(config: dict[str, Any], plant: dict[str, Any]) -> dict[str, Any]:
    from tsa_bench.analysis import diagnose, load_model
    from tsa_bench.shipped import shipped

    hist, out = simulate_point(config["protocol"], plant, int(config["bench"]["seed"]),
                               float(config["bench"]["settle_s"]))
    model = load_model(shipped("bench") / f"{config['diagnose']['model']}.yaml")
    t0 = time.perf_counter()
    result = diagnose([run_data("point", hist, out)], model, None, max_causes=int(config["diagnose"]["max_causes"]),
                      seed=int(config["diagnose"]["seed"]))
    seconds = time.perf_counter() - t0
    hidden = config["effect"]["name"]
    causes = list(result.causes)
    return {"verdict": result.verdict, "causes": "+".join(causes), "alarm": result.verdict != "explained",
            "detected": None if hidden == "none" else bool(result.verdict == "named" and causes[:1] == [hidden]),
            "run_length_min": float(hist["t"][-1] - hist["t"][0]) / 60.0, "samples": int(len(hist["t"])),
            "diagnose_s": seconds}
