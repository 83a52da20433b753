"""`tsa-bench estimate`: load and strain from resistance and twist, on a held-out run whose load
changes are not told to the estimator."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.models import load_strain as ls
from tsa_bench.store.reader import read_run
from tests.control.helpers import ROOT


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("estimate")
    paths = {}
    for name, seed in (("estimate-load-training", 1), ("estimate-load-changes", 2)):
        out = d / f"{name}.h5"
        res = CliRunner().invoke(main, ["run", str(ROOT / f"configs/protocols/{name}.yaml"), "--bench",
                                        str(ROOT / "configs/bench/sim-scheme2-4ply.yaml"), "--seed", str(seed),
                                        "--output", str(out)])
        assert res.exit_code == 0, res.output
        paths[name] = out
    model = d / "load-strain.json"
    res = CliRunner().invoke(main, ["estimate", "--train", str(paths["estimate-load-training"]), "--out", str(model)])
    assert res.exit_code == 0, res.output
    return paths, model


def test_load_within_10_percent_and_strain_within_half_a_percent_of_length(runs):
    paths, model_file = runs
    run = read_run(paths["estimate-load-changes"])
    model = ls.load(model_file)
    est = ls.estimate(model, run)
    s = ls.summary(est, run)
    assert s["n"] > 1500
    assert s["load_err_max_percent"] <= 10.0 and s["length_err_max_percent"] <= 0.5, s
    # the uncertainty is stated and of the size of the errors seen (not zero, not huge)
    ok = np.isfinite(est.load_N)
    assert 0.001 < np.median(est.load_sd_N[ok]) < 0.2 and np.all(est.strain_sd[ok] > 0)
    # unannounced: the estimate follows the change in the middle of the last hold
    load = np.asarray(run.samples["load"])
    last = ok & (load == load[-1])
    assert abs(np.median(est.load_N[last][-50:]) - load[-1]) < 0.1 * load[-1]


def test_the_command_prints_holds_and_errors_and_refuses_bad_input(runs, tmp_path):
    paths, model_file = runs
    res = CliRunner().invoke(main, ["estimate", str(paths["estimate-load-changes"]), "--model", str(model_file)])
    assert res.exit_code == 0, res.output
    assert "load_N" in res.output and "load error vs the declared load: max" in res.output
    doc = json.loads(model_file.read_text())
    assert doc["format"] == ls.FORMAT and doc["units"]["b"][1] == "ohm/mm"
    wrong = CliRunner().invoke(main, ["estimate", str(paths["estimate-load-changes"]), "--model",
                                      str(ROOT / "configs/models/scheme2-self-sensing.json")])
    assert wrong.exit_code == 2 and "expected 'tsa-bench/load-strain-model'" in wrong.output
    one_load = CliRunner().invoke(main, ["estimate", "--train", str(paths["estimate-load-changes"]), "--out",
                                         str(tmp_path / "m.json")])
    assert one_load.exit_code == 2 and "settled holds" in one_load.output
    missing = CliRunner().invoke(main, ["estimate", str(tmp_path / "none.h5"), "--model", str(model_file)])
    assert missing.exit_code == 2 and "Traceback" not in missing.output
