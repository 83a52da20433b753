"""Judge the simulated plant against measured runs (``tsa-bench diagnose``).

Units: time in s, length in mm, resistance in ohm, load in g inside (N in files).

Contract: :func:`diagnose` calibrates the judged model on the training part of the
runs, tests its residuals against a noise model estimated from the data, screens and
refits candidate effects (library effects in several physical forms), names a cause
only when it passes a held-out, block-bootstrapped gate and explains most of the
structure, and always ends in a verdict: ``explained``, ``named``, ``unexplained`` or
``model_mismatch`` (docs/diagnose.md). :func:`load_model` reads the ``plant`` mapping of
a bench YAML (None: configs/bench/sim-baseline.yaml).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tsa_bench.analysis.result import VERDICTS, Candidate, DiagnoseResult, Gain, NamedCause
from tsa_bench.shipped import shipped

CONFIG_DIR = shipped("bench")
BASELINE = CONFIG_DIR / "sim-baseline.yaml"


def load_model(path: str | Path | None) -> dict[str, Any]:
    """Plant config mapping of a bench YAML (validated); None -> the thesis-level baseline."""
    from tsa_bench.bench import load_bench
    from tsa_bench.sim.plant import plant_from_config

    bench = load_bench(BASELINE if path is None else path)
    plant = dict(bench.plant)
    plant_from_config(plant, seed=0)  # validate: raises ValueError naming a bad key
    return plant


from tsa_bench.analysis.diagnose import diagnose  # noqa: E402
from tsa_bench.analysis.holdout import HoldoutError  # noqa: E402

__all__ = ["Candidate", "Gain", "NamedCause", "DiagnoseResult", "VERDICTS", "HoldoutError", "diagnose",
           "load_model", "BASELINE"]
