"""`tsa-bench diagnose`: bad input exits 2 naming the file; the verdict first; output beside the
run; progress on stderr; Ctrl-C exits 130 writing nothing; end to end on a small simulated run."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from diagnose_helpers import write_minimal_run

from tsa_bench.cli.diagnose import diagnose

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]




def invoke(*args):
    return CliRunner().invoke(diagnose, [str(a) for a in args], catch_exceptions=False)


def test_missing_run_file(tmp_path):
    res = invoke(tmp_path / "nope.h5", "--out", tmp_path / "o")
    assert res.exit_code == 2
    assert "error:" in res.output and "nope.h5" in res.output and "no such file" in res.output
    assert not (tmp_path / "o").exists()


def test_not_a_run_file(tmp_path):
    bad = tmp_path / "notes.h5"
    bad.write_text("this is not HDF5")
    res = invoke(bad, "--out", tmp_path / "o")
    assert res.exit_code == 2 and "notes.h5" in res.output and "not a readable HDF5 file" in res.output


def test_second_run_file_is_checked_too(tmp_path):
    write_minimal_run(tmp_path / "good.h5")
    res = invoke(tmp_path / "good.h5", tmp_path / "other.h5", "--out", tmp_path / "o")
    assert res.exit_code == 2 and "other.h5" in res.output


def test_needs_a_run_file():
    res = CliRunner().invoke(diagnose, [])
    assert res.exit_code == 2


def test_bad_model_file(tmp_path):
    write_minimal_run(tmp_path / "good.h5")
    model = tmp_path / "broken-model.yaml"
    model.write_text("plant: [this, is, not, a, plant\n")
    res = invoke(tmp_path / "good.h5", "--model", model, "--out", tmp_path / "o")
    assert res.exit_code == 2 and "error:" in res.output and "broken-model.yaml" in res.output


def test_missing_model_file(tmp_path):
    write_minimal_run(tmp_path / "good.h5")
    res = invoke(tmp_path / "good.h5", "--model", tmp_path / "absent.yaml", "--out", tmp_path / "o")
    assert res.exit_code == 2 and "absent.yaml" in res.output


def test_a_validation_run_must_not_be_a_diagnosed_one_and_predict_options_fit_the_file(tmp_path):
    from tsa_bench.cli.models import predict_cmd

    write_minimal_run(tmp_path / "good.h5", n=400)
    res = invoke(tmp_path / "good.h5", "--validate", tmp_path / "good.h5", "--out", tmp_path / "o")
    assert res.exit_code == 2 and "validation run must not be one of the runs" in res.output
    assert not (tmp_path / "o").exists()
    model = ROOT / "configs" / "bench" / "sim-baseline.yaml"
    bad = CliRunner().invoke(predict_cmd, [str(model), str(tmp_path / "good.h5"), "--write-prediction",
                                           str(tmp_path / "p.h5")])
    assert bad.exit_code == 2 and "saved fit model" in bad.output and not (tmp_path / "p.h5").exists()


def test_bad_holdout(tmp_path):
    write_minimal_run(tmp_path / "good.h5", n=400)
    res = invoke(tmp_path / "good.h5", "--holdout", "bogus:spec", "--out", tmp_path / "o")
    assert res.exit_code == 2 and "error:" in res.output and "bogus:spec" in res.output


def _speed_module():
    spec = importlib.util.spec_from_file_location("diagnose_speed", ROOT / "scripts" / "bench" / "diagnose_speed.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_end_to_end_on_a_small_simulated_run(tmp_path, monkeypatch):
    gen = _speed_module()
    from tsa_bench.analysis import load_model
    model = load_model(None)
    run = gen.simulate_run(gen.with_hidden_effect(model, "resistance_transient_decay"), HERE / "small.yaml",
                           tmp_path / "data" / "small.h5", seed=3)
    monkeypatch.chdir(tmp_path)
    res = invoke(run, "--max-causes", "1")
    assert res.exit_code == 0, res.output
    out = tmp_path / "data" / "small_diagnose"          # beside the run, not in the current directory
    for name in ("report.txt", "fit.png", "residuals.png", "diagnose.json"):
        assert (out / name).stat().st_size > 0, name
    data = json.loads((out / "diagnose.json").read_text())
    assert data["verdict"] == "named" and data["causes"] == ["resistance_transient_decay"], data["summary"]
    assert res.stdout.startswith("VERDICT: named: resistance_transient_decay")
    assert f"wrote {out / 'report.txt'}" in res.stdout
    assert "diagnose: [stage 2/6 calibration] calibrating the judged model" in res.stderr
    assert "diagnose: [stage 6/6 final checks]" in res.stderr and "diagnose:" not in res.stdout
    assert data["provenance"]["inputs"][0]["sha256"] and data["provenance"]["model"]["path"].endswith(
        "sim-baseline.yaml")


def test_the_loop_extended_model_predict_validate_rediagnose_and_run(tmp_path):
    """diagnose --write-model --validate, then the file: predict gives the reported held-out RMSE
    back bit for bit, diagnose --model on the same data says explained, run --bench simulates it."""
    from tsa_bench.analysis import load_model
    from tsa_bench.bench import load_bench
    from tsa_bench.cli import main
    from tsa_bench.cli.models import predict_cmd

    gen = _speed_module()
    truth = gen.with_hidden_effect(load_model(None), "resistance_transient_decay")
    run = gen.simulate_run(truth, HERE / "small.yaml", tmp_path / "a.h5", seed=3)
    other = gen.simulate_run(truth, HERE / "small.yaml", tmp_path / "b.h5", seed=4)
    model = tmp_path / "extended.yaml"
    res = invoke(run, "--write-model", model, "--validate", other, "--out", tmp_path / "d1", "-q")
    assert res.exit_code == 0, res.output
    data = json.loads((tmp_path / "d1" / "diagnose.json").read_text())
    assert data["causes"] == ["resistance_transient_decay"] and f"wrote {model}" in res.stdout
    plant = load_bench(model).plant
    on = {k for k, v in plant["effects"].items() if v.get("enabled")}
    assert "resistance_transient_decay" in on
    assert not on & {"missed_steps", "twist_hysteresis", "load_dependence", "length_creep", "thermal_dynamics"}
    assert "Prospective validation" in res.stdout and len(data["validation"]) == 2
    for g in data["gain"]:
        lo, hi = g["after_ci95"]
        assert lo <= g["heldout_rmse_after"] <= hi and g["noise_rms"] > 0
    pj = tmp_path / "p.json"
    pr = CliRunner().invoke(predict_cmd, [str(model), str(run), "--json", str(pj)], catch_exceptions=False)
    assert pr.exit_code == 0, pr.output
    figures = json.loads(pj.read_text())["outputs"]
    for g in data["gain"]:
        assert figures[g["output"]]["rmse_heldout"] == g["heldout_rmse_after"]      # bit for bit
    again = invoke(run, "--model", model, "--out", tmp_path / "d2", "-q")
    assert again.exit_code == 0 and again.stdout.startswith("VERDICT: explained"), again.stdout[:400]
    assert invoke(run, "--write-model", model, "--out", tmp_path / "d3").exit_code == 2     # never overwritten
    sim = CliRunner().invoke(main, ["run", str(HERE / "small.yaml"), "--bench", str(model), "--output",
                                    str(tmp_path / "c.h5")], catch_exceptions=False)
    assert sim.exit_code == 0 and (tmp_path / "c.h5").stat().st_size > 0, sim.output


@pytest.fixture
def fake_engine(monkeypatch):
    """The real CLI with the engine's diagnose replaced by a hand-built result."""
    from diagnose_helpers import build_result

    from tsa_bench import analysis

    calls = {}

    def diagnose(runs, model, holdout=None, *, max_causes=3, seed=0, progress=None, outputs=None, model_path=None,
                 validate=None):
        if holdout == "bad":
            raise analysis.HoldoutError(f"holdout {holdout!r}: expected run:N, after:SECONDS or fraction:F")
        if holdout == "interrupt":
            raise KeyboardInterrupt
        progress("working")
        calls.update(runs=runs, holdout=holdout, max_causes=max_causes, outputs=outputs, model_path=model_path)
        return build_result()

    monkeypatch.setattr(analysis, "diagnose", diagnose)
    return calls


def test_cli_writes_report_figures_and_json_beside_the_run(tmp_path, monkeypatch, fake_engine):
    (tmp_path / "data").mkdir()
    write_minimal_run(tmp_path / "data" / "bench run.h5")
    write_minimal_run(tmp_path / "data" / "second.h5")
    monkeypatch.chdir(tmp_path)
    res = invoke("data/bench run.h5", "data/second.h5", "--holdout", "run:1", "--max-causes", "2", "--outputs",
                 "length")
    assert res.exit_code == 0, res.output
    assert len(fake_engine["runs"]) == 2 and fake_engine["holdout"] == "run:1" and fake_engine["max_causes"] == 2
    assert fake_engine["outputs"] == ("length",) and fake_engine["model_path"].endswith("sim-baseline.yaml")
    out = tmp_path / "data" / "bench run_diagnose"
    for name in ("report.txt", "fit.png", "residuals.png", "cause.png", "diagnose.json"):
        assert (out / name).stat().st_size > 0, name
    assert res.stdout.splitlines()[0] == "VERDICT: named: resistance_transient_decay (stretched exponential, " \
                                         "confidence 0.98)"
    assert "diagnose: working" in res.stderr
    assert json.loads((out / "diagnose.json").read_text())["verdict"] == "named"


def test_cli_json_and_out_options(tmp_path, fake_engine):
    write_minimal_run(tmp_path / "a.h5")
    res = invoke(tmp_path / "a.h5", "--out", tmp_path / "rep", "--json", tmp_path / "j" / "r.json", "-q")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "rep" / "report.txt").exists() and (tmp_path / "j" / "r.json").exists()
    assert not (tmp_path / "rep" / "diagnose.json").exists() and res.stderr == ""


def test_cli_bad_holdout_from_engine_exits_2(tmp_path, fake_engine):
    write_minimal_run(tmp_path / "a.h5")
    res = invoke(tmp_path / "a.h5", "--holdout", "bad", "--out", tmp_path / "o")
    assert res.exit_code == 2 and "error: holdout 'bad'" in res.stderr and len(res.stderr.splitlines()) <= 3
    assert not (tmp_path / "o").exists()


def test_cli_ctrl_c_exits_130_writing_nothing(tmp_path, fake_engine):
    write_minimal_run(tmp_path / "a.h5")
    res = invoke(tmp_path / "a.h5", "--holdout", "interrupt", "--out", tmp_path / "o")
    assert res.exit_code == 130 and "interrupted" in res.stderr and not (tmp_path / "o").exists()


@pytest.mark.parametrize("bad", ["torque", "", "length,speed"])
def test_cli_bad_outputs_exit_2(tmp_path, bad):
    write_minimal_run(tmp_path / "a.h5")
    res = invoke(tmp_path / "a.h5", "--outputs", bad, "--out", tmp_path / "o")
    assert res.exit_code == 2 and "--outputs" in res.stderr and not (tmp_path / "o").exists()


def test_cli_run_without_twist_is_a_mismatch_verdict(tmp_path):
    """A run whose turns column is all NaN (a CSV import without it): verdict model_mismatch, exit 0."""
    import h5py
    write_minimal_run(tmp_path / "a.h5", n=400)
    with h5py.File(tmp_path / "a.h5", "r+") as f:
        f["samples/turns"][...] = float("nan")
    res = invoke(tmp_path / "a.h5", "--out", tmp_path / "o", "-q")
    assert res.exit_code == 0, res.output
    assert res.stdout.startswith("VERDICT: model_mismatch: ") and "turns" in res.stdout.splitlines()[0]
    assert json.loads((tmp_path / "o" / "diagnose.json").read_text())["verdict"] == "model_mismatch"


def test_the_verdict_goes_on_the_run_s_catalogue_row(tmp_path, fake_engine):
    from tsa_bench import catalogue

    run = tmp_path / "data" / "r.h5"
    run.parent.mkdir()
    write_minimal_run(run)
    assert invoke(run, "--out", tmp_path / "o", "--catalogue", "none").exit_code == 0
    assert not (run.parent / "catalogue.sqlite").exists()
    assert invoke(run, "--out", tmp_path / "o2").exit_code == 0    # registered beside the run, verdict and all
    with catalogue.open(run.parent) as cat:
        row = cat.by_path(run)
    assert row.verdict == "named" and row.verdict_detail == "resistance_transient_decay"
    assert row.diagnosed is not None and row.sha256 is not None and row.file_state() == "ok"
