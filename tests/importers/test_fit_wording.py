"""What fit and diagnose say about imported runs (issue 29, items 9 and 11): notes that are true of the run at hand."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from click.testing import CliRunner

from tests.importers.fixtures import run_import
from tsa_bench.analysis.context import Context
from tsa_bench.analysis.inputs import missing_inputs, run_inputs
from tsa_bench.analysis.verdict import follows_text
from tsa_bench.cli import main
from tsa_bench.cli.diagnose import _no_segments_hint
from tsa_bench.store import read_run


def _fit(tmp_path, run, *args):   # a model file per run (an existing one is not replaced without --force)
    return CliRunner().invoke(main, ["fit", "polynomial", str(run), "--out", str(tmp_path / f"{run.stem}.json"),
                                     *args])


def test_percent_errors_near_zero_come_with_a_caution(tmp_path):
    rows = "".join(f"{k * 0.1:.1f},{(k // 20) * 1.0:g},{-0.5 + 0.3 * (k // 20) + 0.001 * (k % 2):.4f}\n"
                   for k in range(200))
    res, out = run_import(tmp_path, "t [s],turns [turn],length [mm]\n" + rows)
    assert res.exit_code == 0, res.output
    fit = _fit(tmp_path, out)
    assert fit.exit_code == 0, fit.output
    assert "length comes near zero" in fit.output and "percent errors (3.21)" in fit.output
    assert "tsa-bench import --offset length=L0" in fit.output
    res, out = run_import(tmp_path, "t [s],turns [turn],length [mm]\n" + rows, "--offset", "length=250", out="b.h5")
    fit = _fit(tmp_path, out)
    assert fit.exit_code == 0 and "comes near zero" not in fit.output


def test_a_note_on_many_loads_lists_a_few_and_counts_them(tmp_path):
    rows = "".join(f"{k * 0.1:.1f},{(k // 20) % 5:g},{250 - (k // 20) % 5:.1f},{100 + 10 * (k // 20)}\n"
                   for k in range(30 * 20))
    res, out = run_import(tmp_path, "t [s],turns [turn],length [mm],load [g]\n" + rows)
    assert res.exit_code == 0, res.output
    fit = _fit(tmp_path, out)
    assert fit.exit_code == 0, fit.output
    note = next(ln for ln in fit.output.splitlines() if "loads (" in ln)
    assert "holds samples at 30 loads (100, 110, 120, 130, 140, 150, 160, ... 390 g (30 in all))" in note
    assert "200 g" not in note                                # the middle of the list is not printed


def test_both_outputs_unmeasured_get_one_reason_and_one_remedy(tmp_path):
    res, out = run_import(tmp_path, "t [s],turns [turn],temperature [degC]\n" +
                          "".join(f"{k * 0.1:.1f},{k // 10:g},{20 + k * 0.01:.2f}\n" for k in range(100)))
    assert res.exit_code == 0, res.output
    missing = missing_inputs([run_inputs(read_run(out))], ("length", "resistance"))
    unmeasured = [(p, r) for p, r in missing if "not measured" in p]
    assert len(unmeasured) == 1 and "length and resistance are not measured" in unmeasured[0][0]
    assert "--outputs" not in unmeasured[0][1]               # no "judge the other one alone" for either


def test_a_residual_following_length_is_no_scale_error_when_nothing_drives_the_model():
    test = {"follows": [{"signal": "length", "share": 0.8}]}
    assert "a sensor scale error" in follows_text("length", test)
    said = follows_text("length", {**test, "undriven": True})
    assert "sensor scale error" not in said and "no input of the model drives the actuator" in said
    still = SimpleNamespace(turns=np.zeros(50), scored=np.ones(50, bool), volts=np.zeros(50))
    moved = SimpleNamespace(turns=np.arange(50.0), scored=np.ones(50, bool), volts=np.zeros(50))
    heated = SimpleNamespace(turns=np.zeros(50), scored=np.ones(50, bool), volts=np.r_[np.zeros(25), np.ones(25)])
    assert Context.undriven.fget(SimpleNamespace(inputs=[still]))
    assert not Context.undriven.fget(SimpleNamespace(inputs=[still, moved]))
    assert not Context.undriven.fget(SimpleNamespace(inputs=[heated]))


def test_diagnose_does_not_suggest_infer_after_infer_found_nothing(tmp_path):
    res, out = run_import(tmp_path, "t [s],length [mm]\n" + "".join(f"{k * 0.1:.1f},{100 + 0.01 * k:.2f}\n"
                                                                   for k in range(50)))
    assert res.exit_code == 0 and "segments: none inferred" in res.output
    hint = _no_segments_hint(read_run(out))
    assert "--segments infer finds them" not in hint and "its import inferred none" in hint
    res, out = run_import(tmp_path, None, "--segments", "none", out="b.h5")
    assert "--segments infer finds them" in _no_segments_hint(read_run(out))
