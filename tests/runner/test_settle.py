"""hold_until_settled on the simulated bench: a hold ends when its criterion holds, and
not long after; without settling it ends at its maximum."""

from __future__ import annotations

import json

import numpy as np

from tests.runner.helpers import plan_from_text, run_plan
from tsa_bench.runner.settle import CHUNK_S, IN_FLIGHT, slope
from tsa_bench.store import read_run

SETTLE = """name: settle
sampling_period_s: 0.1
defaults: {rate_turns_per_s: 3, accel_turns_per_s2: 30}
steps:
  - move_to: {turns: 30}
  - hold_until_settled: {max_duration_s: 400, window_s: 20, max_dR_dt_ohm_per_s: 5.0e-5, max_dL_dt_mm_per_s: 0.004}
  - move_to: {turns: 40}
  - hold_until_settled: {max_duration_s: 25, window_s: 10, max_dR_dt_ohm_per_s: 1.0e-9}
  - heater: {voltage_V: 2}
  - hold_until_settled: {max_duration_s: 15, window_s: 5, max_dR_dt_ohm_per_s: 1.0}
  - heater: {voltage_V: 0}
"""


def _criterion_first_holds(t, r, l, t0, t1, window, max_dr, max_dl) -> float | None:
    """The first device time (1 s grid) at which the criterion held over the window before it."""
    for now in np.arange(t0 + window, t1 + 1e-9, 0.1):
        sel = (t > now - window) & (t <= now)
        dr, dl = slope(t[sel], r[sel], window), slope(t[sel], l[sel], window)
        if dr is not None and dl is not None and abs(dr) <= max_dr and abs(dl) <= max_dl:
            return float(now)
    return None


def test_settling_holds_end_when_the_criterion_holds(tmp_path):
    stop, _, path = run_plan(plan_from_text(SETTLE), tmp_path, seed=4)
    assert stop.exit_status == "success", stop.reason
    run = read_run(path)
    seg = {int(row["index"]): row for row in run.segments}
    s = run.samples
    t, r, length = s["t"], s["resistance"], s["length"]

    # 1: settles well before its 400 s maximum, and ends within the chunks it had queued of the
    #    moment its criterion first held (recomputed here from the stored samples)
    first = seg[1]
    out = json.loads(first["params"])
    duration = first["t_end"] - first["t_start"]
    assert out["settled"] is True and 20 <= duration < 300, (duration, out)
    assert abs(out["dR_dt_ohm_per_s"]) <= 5e-5 and abs(out["dL_dt_mm_per_s"]) <= 0.004
    mine = s["segment"] == 1
    held = _criterion_first_holds(t[mine], r[mine], length[mine], first["t_start"], first["t_end"], 20, 5e-5, 0.004)
    assert held is not None
    assert held <= first["t_end"] + 1e-6 and first["t_end"] - held <= (IN_FLIGHT + 1) * CHUNK_S + 0.5, \
        (held, first["t_end"])
    # ... and it had not held long before: the hold did not wait past the first moment by more than the lag
    early = _criterion_first_holds(t[mine], r[mine], length[mine], first["t_start"], held - 1.5, 20, 5e-5, 0.004)
    assert early is None or held - early < 1.0

    # 3: a criterion no real signal meets (1 nOhm/s) ends at its maximum, not settled
    never = seg[3]
    assert json.loads(never["params"])["settled"] is False
    assert abs((never["t_end"] - never["t_start"]) - 25) < 0.2
    # 5: with the heater on the resistance is not measured, so it cannot settle on resistance
    heated = seg[5]
    assert json.loads(heated["params"])["settled"] is False and abs(heated["t_end"] - heated["t_start"] - 15) < 0.2
    kinds = [e["kind"].decode() for e in run.events]
    assert kinds.count("settled") == 1 and kinds.count("not_settled") == 2
    assert "queue_underrun" not in kinds  # the short DWELLs keep the device fed
