"""The diagnose report: the verdict first, one screen, figures, strict JSON."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from diagnose_helpers import build_result, write_minimal_run

from tsa_bench.report.diagnose_report import decimate_minmax, format_report, write_json, write_report
from tsa_bench.sim.effects import describe_forms
from tsa_bench.store import read_run

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SCREEN_LINES = 60


@pytest.mark.parametrize("verdict", ["explained", "named", "unexplained", "model_mismatch"])
def test_verdict_is_the_first_line_and_the_report_fits_one_screen(verdict):
    result = build_result(verdict=verdict)
    text = format_report(result)
    lines = text.splitlines()
    assert lines[0] == f"VERDICT: {result.summary}" and lines[0].startswith(f"VERDICT: {verdict}")
    assert len(lines) <= SCREEN_LINES, len(lines)
    assert not re.search(r"\bnan\b", text.lower().replace("all nan", ""))


def test_named_report_gives_form_confidence_meaning_source_and_gain(tmp_path, result_with_cause):
    paths = write_report(result_with_cause, [], tmp_path / "out")
    assert set(paths) == {"report", "fit", "residuals", "cause"}
    for key in ("fit", "residuals", "cause"):
        data = paths[key].read_bytes()
        assert data.startswith(PNG_MAGIC) and len(data) > 5000, key
    text = paths["report"].read_text()
    form = next(d for d in describe_forms() if d["name"] == "resistance_transient_stretched")
    assert "1. resistance_transient_decay (stretched exponential)  confidence 0.98, form 0.87" in text
    assert form["doc"].replace("``", "") in text and form["source"] in text
    assert "412 noise variances per sample (95 % 301 to 533)" in text.replace("412.5", "412")
    assert "0.0312 ohm" in text and "0.00105 ohm" in text and "+96.6 %" in text
    assert re.search(r"resistance_transient_stretched\.amp_ohm +- +-> +0\.0271 ohm", text)
    assert "not determined by these data" in text and "string_compliance.stiffness_N" in text


def test_explained_report_has_no_cause_figure(tmp_path, result_clean):
    paths = write_report(result_clean, [], tmp_path)
    text = paths["report"].read_text()
    assert "VERDICT: explained:" in text and "Named causes" not in text
    assert "cause" not in paths and not (tmp_path / "cause.png").exists()
    assert paths["fit"].stat().st_size > 5000


def test_unexplained_and_mismatch_say_what_is_left_and_what_to_do():
    text = format_report(build_result(verdict="unexplained"))
    assert "Unexplained: resistance residual follows the time since the motor stopped" in text
    assert "follows time_since_stop 91 %" in text
    text = format_report(build_result(verdict="model_mismatch"))
    assert "MISMATCH: run.h5: no motor twist recorded" in text and "what to do: record or import a turns" in text


def test_cause_without_signal_skips_only_that_figure(tmp_path):
    paths = write_report(build_result(with_signal=False), [], tmp_path)
    assert {"report", "fit", "residuals"} <= set(paths) and "cause" not in paths


def test_mismatch_without_series_writes_the_text_only(tmp_path):
    paths = write_report(build_result(verdict="model_mismatch"), [], tmp_path)
    assert set(paths) == {"report"}


def test_json_is_strict(tmp_path, result_with_cause):
    result_with_cause.gain[0].heldout_rmse_after = float("nan")
    data = json.loads(write_json(result_with_cause, tmp_path / "d.json").read_text())
    assert data["verdict"] == "named" and data["causes"] == ["resistance_transient_decay"]
    assert data["named"][0]["form"] == "stretched exponential" and data["named"][0]["confidence"] == 0.98
    assert data["gain"][0]["heldout_rmse_after"] is None
    assert set(data["residual_tests"]) == {"before", "after"}


def test_figures_work_on_100k_samples(tmp_path):
    paths = write_report(build_result(n=120_000), [], tmp_path)
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
    write_minimal_run(tmp_path / "a.h5", n=50)
    text = format_report(result_with_cause, [read_run(tmp_path / "a.h5")])
    assert "a.h5: 50 samples, 4.9 s, 10 Hz, exit success" in text
