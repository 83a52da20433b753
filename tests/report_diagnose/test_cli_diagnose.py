"""`tsa-bench diagnose`: bad input exits 2 naming the file; end to end on a small simulated run."""

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
    off = gen.effects_off(model)
    effect = next((e for e in gen.PREFERRED if e in off), None)
    assert effect is not None, f"the baseline model leaves none of {gen.PREFERRED} off"
    run = gen.simulate_run(gen.with_hidden_effect(model, effect), HERE / "small.yaml", tmp_path / "small.h5", seed=3)
    monkeypatch.chdir(tmp_path)
    res = invoke(run)
    assert res.exit_code == 0, res.output
    out = tmp_path / "diagnose-small"
    for name in ("report.txt", "fit.png", "residuals.png", "diagnose.json"):
        assert (out / name).stat().st_size > 0, name
    data = json.loads((out / "diagnose.json").read_text())
    assert {"cause", "causes", "candidates", "gain", "residual_tests"} <= set(data)
    assert "VERDICT" in res.output and f"wrote {out / 'report.txt'}" in res.output
    if data["cause"]:
        assert (out / "cause.png").exists() or "cause_signal" not in data


@pytest.fixture
def fake_engine(monkeypatch):
    """A stand-in engine returning a hand-built result: the CLI's happy path without the real engine."""
    import sys
    import types

    import tsa_bench
    from diagnose_helpers import build_result

    calls = {}
    fake = types.ModuleType("tsa_bench.analysis")

    def load_model(path):
        calls["model"] = path
        return {"effects": {}}

    def diagnose(runs, model, holdout=None, *, max_causes=3, seed=0):
        if holdout == "bad":
            raise ValueError(f"holdout {holdout!r}: expected run:N, after:SECONDS or fraction:F")
        calls.update(runs=runs, holdout=holdout, max_causes=max_causes)
        return build_result()

    fake.load_model, fake.diagnose = load_model, diagnose
    monkeypatch.setitem(sys.modules, "tsa_bench.analysis", fake)
    monkeypatch.setattr(tsa_bench, "analysis", fake, raising=False)
    return calls


def test_cli_writes_report_figures_and_json(tmp_path, monkeypatch, fake_engine):
    write_minimal_run(tmp_path / "bench run.h5")
    write_minimal_run(tmp_path / "second.h5")
    monkeypatch.chdir(tmp_path)
    res = invoke("bench run.h5", "second.h5", "--holdout", "run:1", "--max-causes", "2")
    assert res.exit_code == 0, res.output
    assert len(fake_engine["runs"]) == 2 and fake_engine["holdout"] == "run:1" and fake_engine["max_causes"] == 2
    assert fake_engine["model"] is None
    out = tmp_path / "diagnose-bench-run"
    for name in ("report.txt", "fit.png", "residuals.png", "cause.png", "diagnose.json"):
        assert (out / name).stat().st_size > 0, name
    assert "VERDICT: unmodelled effect found: resistance_transient_decay" in res.output
    assert f"wrote {out / 'diagnose.json'}" in res.output
    data = json.loads((out / "diagnose.json").read_text())
    assert data["cause"] == "resistance_transient_decay"


def test_cli_json_and_out_options(tmp_path, fake_engine):
    write_minimal_run(tmp_path / "a.h5")
    res = invoke(tmp_path / "a.h5", "--out", tmp_path / "rep", "--json", tmp_path / "j" / "r.json")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "rep" / "report.txt").exists() and (tmp_path / "j" / "r.json").exists()
    assert not (tmp_path / "rep" / "diagnose.json").exists()


def test_cli_bad_holdout_from_engine_exits_2(tmp_path, fake_engine):
    write_minimal_run(tmp_path / "a.h5")
    res = invoke(tmp_path / "a.h5", "--holdout", "bad", "--out", tmp_path / "o")
    assert res.exit_code == 2 and "error: holdout 'bad'" in res.output
    assert not (tmp_path / "o").exists()
