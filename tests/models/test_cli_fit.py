"""`tsa-bench fit | predict | manipulator` on simulated runs; clear errors on bad input."""

from __future__ import annotations

import json

from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.models.saved import ModelFileError, load_model_file
from tests.models.generator_plant import generator_plant
from tsa_bench.reproduce.runs import history, simulate_history, step_duration_steps, twist_sweep_steps, write_run


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    out = {}
    for name, steps, dt in (("a", step_duration_steps(6.0, cycles=1), 0.1), ("b", step_duration_steps(17.0, cycles=1), 0.1),
                            ("sweep", twist_sweep_steps(81.0), 0.1)):
        h = history(steps, dt_s=dt, load_g=250.0 if name == "sweep" else 350.0)
        plant = "sim-4ply" if name == "sweep" else generator_plant()
        out[name] = str(write_run(d / f"{name}.h5", h, simulate_history(h, plant)))
    out["dir"] = d
    return out


def test_fit_predict_round_trip(runs) -> None:
    model = runs["dir"] / "sr.json"
    res = CliRunner().invoke(main, ["fit", "strain-resistance", runs["a"], "--validate", runs["b"], "--out", str(model)])
    assert res.exit_code == 0, res.output
    assert "identification" in res.output and "validation" in res.output
    saved = load_model_file(model)
    assert saved.training_files == [runs["a"]] and runs["b"] in saved.metrics["validation"]
    assert saved.parameters["b1"]["unit"] == "ohm" and saved.parameters["Lambda"]["unit"] == "1/s"
    before = Path(runs["b"]).read_bytes()
    out = runs["dir"] / "b-predicted.h5"
    res = CliRunner().invoke(main, ["predict", str(model), runs["b"], "--write-prediction", str(out)])
    assert res.exit_code == 0, res.output
    assert Path(runs["b"]).read_bytes() == before  # the recorded run is never changed
    with h5py.File(out, "r") as f:
        pred = f["samples/predicted_resistance"][()]
        meas = f["samples/resistance"][()]
        assert f["samples/predicted_resistance"].attrs["units"] == "ohm"
        assert f.attrs["derived_from"] == Path(runs["b"]).name
    again = CliRunner().invoke(main, ["predict", str(model), runs["b"], "--write-prediction", str(out)])
    assert again.exit_code == 2 and "already exists" in again.output  # never overwritten silently
    ok = np.isfinite(pred)
    assert ok.sum() > 100 and np.mean(np.abs(pred[ok] - meas[ok])) < 0.01
    assert np.mean(np.abs(pred[ok] - meas[ok])) == pytest.approx(saved.metrics["validation"][runs["b"]]["e_aver"])


def test_fit_preisach_with_input_option(runs) -> None:
    model = runs["dir"] / "pre.json"
    res = CliRunner().invoke(main, ["fit", "preisach", runs["sweep"], "--input", "turns", "--output", "length",
                                    "--out", str(model)])
    assert res.exit_code == 0, res.output
    doc = json.loads(model.read_text())
    assert doc["input"] == {"column": "turns", "unit": "turn"} and len(doc["parameters"]["weights"]["value"]) == 210


@pytest.mark.parametrize("args, needle", [
    (["fit", "nonsense", "X.h5", "--out", "m.json"], "nonsense"),
    (["fit", "polynomial", "missing.h5", "--out", "m.json"], "missing.h5: no such file"),
    (["fit", "polynomial", "RUN", "--input", "heater_voltage", "--out", "m.json"], "heater_voltage is never above 0 V"),
    (["fit", "self-sensing", "RUN", "--input", "turns", "--out", "m.json"], "maps resistance -> length"),
    (["predict", "missing.json", "RUN"], "missing.json: no such file"),
])
def test_errors_name_file_and_problem(runs, tmp_path, args, needle) -> None:
    args = [runs["a"] if a == "RUN" else str(tmp_path / a) if a.endswith((".h5", ".json")) and a != "X.h5" else a
            for a in args]
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 2
    assert needle in res.output


def test_run_lacking_a_column_and_bad_model_file(runs, tmp_path) -> None:
    broken = tmp_path / "broken.h5"
    with h5py.File(runs["a"], "r") as src, h5py.File(broken, "w") as dst:
        for k, v in src.attrs.items():
            dst.attrs[k] = v
        for name, ds in src["samples"].items():
            if name != "resistance":
                dst.create_dataset(f"samples/{name}", data=ds[()]).attrs["units"] = ds.attrs["units"]
    res = CliRunner().invoke(main, ["fit", "strain-resistance", str(broken), "--out", str(tmp_path / "m.json")])
    assert res.exit_code == 2 and "broken.h5" in res.output and "resistance" in res.output
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "something-else"}')
    with pytest.raises(ModelFileError, match="bad.json: 'format'"):
        load_model_file(bad)


def test_manipulator_command(repo_root) -> None:
    res = CliRunner().invoke(main, ["manipulator", str(repo_root / "configs" / "manipulator" / "thesis.yaml")])
    assert res.exit_code == 0, res.output
    rng = float(res.output.split("bending range ")[1].split(" deg")[0])
    assert 57 < rng < 63
    assert "steady-state error" in res.output
    res = CliRunner().invoke(main, ["manipulator", "nope.yaml"])
    assert res.exit_code == 2 and "nope.yaml: manipulator file not found" in res.output


@pytest.fixture(scope="module")
def three_load_run(tmp_path_factory, repo_root):
    """The 3-ply twist sweep at 100, 150 and 200 g, recorded through `tsa-bench run`."""
    out = tmp_path_factory.mktemp("loads") / "sweep3.h5"
    res = CliRunner().invoke(main, ["run", str(repo_root / "configs/protocols/twist-sweep-3ply.yaml"),
                                    "--bench", str(repo_root / "configs/bench/sim-3ply.yaml"), "--seed", "1",
                                    "--output", str(out)])
    assert res.exit_code == 0, res.output
    return str(out)


def test_fit_at_one_load(three_load_run, tmp_path) -> None:
    mixed, one = tmp_path / "mixed.json", tmp_path / "one.json"
    res = CliRunner().invoke(main, ["fit", "preisach", three_load_run, "--out", str(mixed)])
    assert res.exit_code == 0, res.output
    assert "3 loads (100, 150, 200 g)" in res.output and "--load-g" in res.output
    res = CliRunner().invoke(main, ["fit", "preisach", three_load_run, "--load-g", "150", "--out", str(one)])
    assert res.exit_code == 0, res.output
    e_mixed = load_model_file(mixed).metrics["identification"][three_load_run]
    e_one = load_model_file(one).metrics["identification"][three_load_run]
    assert e_one["n"] * 2 < e_mixed["n"] < e_one["n"] * 4          # a third of the quasi-static samples
    assert e_one["e_aver"] * 10 < e_mixed["e_aver"]                # one curve per load, as in the thesis
    assert load_model_file(one).options["load_g"] == 150
    res = CliRunner().invoke(main, ["predict", str(one), three_load_run])
    assert res.exit_code == 0 and f" {e_one['n']} " in res.output      # scored at its own load only
    none = str(one.with_name("none.json"))   # (an existing model file is not replaced without --force)
    res = CliRunner().invoke(main, ["fit", "polynomial", three_load_run, "--load-g", "120", "--out", none])
    assert res.exit_code != 0 and "no samples at a load of 120 g (loads: 100 g, 150 g, 200 g)" in res.output
    res = CliRunner().invoke(main, ["fit", "self-sensing", three_load_run, "--load-g", "150", "--out", none])
    assert res.exit_code != 0 and "--load-g applies to preisach and polynomial" in res.output
