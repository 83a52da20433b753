"""The fit runner: identify a thesis model on the point's run, validate it on a reference run.

The identification run is the point's protocol (a staircase: hold time, cycles) with
noise seed ``bench.seed``; the validation run is the same staircase with
``fit.validate_hold_s`` holds and ``fit.validate_cycles`` cycles, noise seed
``bench.seed + 1000``. Models as ``tsa-bench fit`` (docs/models.md): preisach and
polynomial map twist (turns) to length; strain-resistance and self-sensing are fitted on
whole hold curves. Figures: ``identification_e_aver_<unit>``, ``validation_e_aver_<unit>``,
``validation_sigma_<unit>`` (eqs. 3.5-3.6, in the model output's unit),
``validation_mean_percent`` (eq. 3.21) and ``run_length_min``.
"""

from __future__ import annotations

from typing import Any

from tsa_bench.sweep.points.common import run_data, simulate_point


def run(config: dict[str, Any], plant: dict[str, Any]) -> dict[str, Any]:
    from tsa_bench.models.fitting import fit

    proto, bench, spec = config["protocol"], config["bench"], config["fit"]
    seed, settle = int(bench["seed"]), float(bench["settle_s"])
    hist, out = simulate_point(proto, plant, seed, settle)
    val_proto = {**proto, "hold_s": float(spec["validate_hold_s"]), "cycles": int(spec["validate_cycles"])}
    vhist, vout = simulate_point(val_proto, plant, seed + 1000, settle)
    train, check = run_data("identification", hist, out), run_data("validation", vhist, vout)
    model = spec["model"]
    io = {"input_col": "turns", "output_col": "length"} if model in ("preisach", "polynomial") else {}
    saved = fit(model, [train], validate=[check], levels=int(spec["levels"]), **io)
    ident, val = saved.metrics["identification"][train.path], saved.metrics["validation"][check.path]
    unit = str(val.get("unit") or "1").replace("/", "_per_")
    return {f"identification_e_aver_{unit}": float(ident["e_aver"]), f"validation_e_aver_{unit}": float(val["e_aver"]),
            f"validation_sigma_{unit}": float(val["sigma"]), "validation_mean_percent": float(val["mean_percent"]),
            "run_length_min": float(hist["t"][-1] - hist["t"][0]) / 60.0}
