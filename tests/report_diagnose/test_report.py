"""The diagnose report: text a scientist reads in a minute, figures, strict JSON."""

from __future__ import annotations

import json
import re

import numpy as np
from diagnose_helpers import build_result

from tsa_bench.report.diagnose_report import decimate_minmax, format_report, write_json, write_report
from tsa_bench.sim.effects import describe_effects

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _doc(name):
    return next(e for e in describe_effects() if e["name"] == name)


def test_report_names_the_cause_its_meaning_source_and_gain(tmp_path, result_with_cause):
    paths = write_report(result_with_cause, [], tmp_path / "out")
    assert set(paths) == {"report", "fit", "residuals", "cause"}
    for key in ("fit", "residuals", "cause"):
        data = paths[key].read_bytes()
        assert data.startswith(PNG_MAGIC) and len(data) > 5000, key
    text = paths["report"].read_text()
    effect = _doc("resistance_transient_decay")
    assert "VERDICT: unmodelled effect found: resistance_transient_decay" in text
    assert effect["doc"].replace("``", "") in text and effect["source"] in text
    # gain table with units and relative gain
    assert "0.0312 ohm" in text and "0.00105 ohm" in text and "+96.6 %" in text
    assert "0.0512 mm" in text
    # residual structure and the candidate table
    assert "STRUCTURED" in text and "time_since_stop r=+0.52 (bound 0.03)" in text
    lines = text.splitlines()
    head = next(i for i, line in enumerate(lines) if "key evidence" in line)
    assert "resistance_transient_decay" in lines[head + 1] and "delta_bic=-412.5" in lines[head + 1]
    assert lines[head + 1].rstrip().endswith("*")
    # calibrated parameters with their units from the effects library
    assert "resistance_transient_decay.b2_ohm" in text and "-0.0271 ohm" in text
    assert re.search(r"string_compliance\.stiffness_N +30\.2 N\n", text)


def test_no_cause_wording_and_no_cause_figure(tmp_path, result_clean):
    paths = write_report(result_clean, [], tmp_path)
    text = paths["report"].read_text()
    assert "no significant unmodelled effect was found" in text
    assert "Named cause" not in text
    assert "cause" not in paths and not (tmp_path / "cause.png").exists()
    assert paths["fit"].stat().st_size > 5000


def test_cause_without_signal_skips_only_that_figure(tmp_path):
    paths = write_report(build_result(with_signal=False), [], tmp_path)
    assert {"report", "fit", "residuals"} <= set(paths) and "cause" not in paths


def test_json_is_strict(tmp_path, result_with_cause):
    result_with_cause.gain[0].heldout_rmse_after = float("nan")
    p = write_json(result_with_cause, tmp_path / "d.json")
    data = json.loads(p.read_text())  # strict: NaN would not parse back as a number
    assert data["cause"] == "resistance_transient_decay" and data["causes"] == ["resistance_transient_decay"]
    assert data["gain"][0]["heldout_rmse_after"] is None
    assert {"name", "score", "evidence"} <= set(data["candidates"][0])
    assert set(data["residual_tests"]) == {"before", "after"}


def test_figures_work_on_100k_samples(tmp_path):
    result = build_result(n=120_000)
    paths = write_report(result, [], tmp_path)
    assert paths["cause"].stat().st_size > 5000


def test_minmax_decimation_keeps_spikes():
    x = np.arange(100_000, dtype=float)
    y = np.zeros_like(x)
    y[54_321] = 7.0
    y[99_999] = -3.0
    xs, ys = decimate_minmax(x, y, bins=500)
    assert len(xs) <= 1000 and ys.max() == 7.0 and ys.min() == -3.0
    assert np.all(np.diff(xs) >= 0)


def test_report_lists_the_runs(tmp_path, result_with_cause):
    from diagnose_helpers import write_minimal_run

    from tsa_bench.store import read_run
    write_minimal_run(tmp_path / "a.h5", n=50)
    text = format_report(result_with_cause, [read_run(tmp_path / "a.h5")])
    assert "a.h5: 50 samples" in text


def test_calibration_before_after_side_by_side(tmp_path):
    result = build_result()
    result.calibrated = {"before": {"string_compliance": {"stiffness_N": 38.1}},
                         "after": {"string_compliance": {"stiffness_N": 30.1},
                                   "resistance_transient_decay": {"b1_ohm": -0.0017}}}
    text = format_report(result)
    assert re.search(r"string_compliance\.stiffness_N +38\.1 +30\.1 +N\n", text)
    assert re.search(r"resistance_transient_decay\.b1_ohm +- +-0\.0017 +ohm\n", text)
    # signals are listed after the effects, each group by score
    assert text.index("generic signals") > text.index("length_creep")
