"""The reproduce runner: one thesis record (configs/thesis/) on the simulated bench.

Figures: ``simulated`` (in the record's unit, given in ``unit``), ``gap_percent``
(simulated vs thesis), ``agrees`` (within the thesis's own spread) and ``verdict``
(as ``tsa-bench reproduce`` prints it).
"""

from __future__ import annotations

from typing import Any


def run(config: dict[str, Any], plant: dict[str, Any] | None) -> dict[str, Any]:
    from tsa_bench.reproduce.experiments import Lab
    from tsa_bench.reproduce.plan import plan_or_empty
    from tsa_bench.reproduce.records import load_records
    from tsa_bench.reproduce.table import evaluate

    spec = config["reproduce"]
    records = load_records(None)
    chosen = [r for r in records if r.id == spec["record"]]
    if not chosen:
        raise ValueError(f"no thesis record {spec['record']!r}")
    row = evaluate(chosen, Lab(seed=int(spec["seed"]), quick=bool(spec["quick"])), plan_or_empty(records))[0]
    return {"simulated": row.simulated, "unit": row.unit, "gap_percent": row.gap_percent,
            "agrees": row.verdict == "agrees", "verdict": row.verdict}
