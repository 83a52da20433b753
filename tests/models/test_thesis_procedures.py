"""The thesis's chapter-3 procedures reproduced on simulated runs (short runs; the script does the full size)."""

from __future__ import annotations

import numpy as np
import pytest

from tsa_bench.models.fitting import from_saved
from tsa_bench.reproduce.procedures import preisach_vs_polynomial, step_duration_procedure


@pytest.fixture(scope="module")
def step_results(tmp_path_factory):
    return step_duration_procedure(tmp_path_factory.mktemp("steps"), cycles=1, seed=3)


def test_strain_resistance_errors_in_the_thesis_range(step_results) -> None:
    """The default bench is calibrated to the thesis's errors (configs/thesis/calibration.yaml):
    identification 0.19-0.29 %, validation 0.55-0.65 % of y; within their factor-2 tolerance,
    not an order of magnitude below as a noise-free plant would give."""
    rows = step_results["strain-resistance"]["rows"]
    assert {r["step_s"] for r in rows if r["set"] == "validation"} == {2.4, 17.0, 98.0}
    for r in rows:
        assert r["unit"] == "ohm" and r["n"] > 100
        assert 0.19 / 2 < r["mean_percent"] < 0.65 * 2, r


def test_transient_decay_recovered(step_results) -> None:
    # the simulated plant uses the thesis's Table 3.3 values b1 = -1.71e-3, b2 = -2.68e-2 ohm
    model = from_saved(step_results["strain-resistance"]["saved"])
    assert model.b1_ohm == pytest.approx(-1.71e-3, rel=0.05)
    assert model.b2_ohm == pytest.approx(-2.68e-2, rel=0.05)


def test_self_sensing_errors_near_the_thesis_range(step_results) -> None:
    """Thesis: 0.086-0.14 % of L. The calibrated bench's run-to-run resistance offsets make the
    validation runs err up to about 3x more (a named disagreement in configs/thesis/calibration.yaml)."""
    rows = step_results["self-sensing"]["rows"]
    for r in rows:
        assert r["unit"] == "mm" and r["n"] > 100
        assert 0.086 / 2 < r["mean_percent"] < 0.5, r


def test_self_sensing_beats_a_resistance_only_static_map(step_results) -> None:
    # a sanity yardstick: the inverse must be better than predicting the mean length (with the
    # calibrated scatter and this run's 3 mm of travel, 1.5-2.5x better)
    saved = step_results["self-sensing"]["saved"]
    for path, m in saved.metrics["validation"].items():
        from tsa_bench.store.reader import read_run
        run = read_run(path)
        length = run.samples["length"]
        moving = run.samples["motor_moving"].astype(bool)
        naive = np.mean(np.abs(length[~moving] - np.mean(length[~moving])))
        assert m["e_aver"] * 1.4 < naive


def test_preisach_beats_polynomial_where_hysteresis_shows(tmp_path) -> None:
    rows = preisach_vs_polynomial(tmp_path, strings=("4-ply",), heat_hold_s=40.0)
    assert len(rows) == 6
    for r in rows:
        assert r["preisach_e_aver_mm"] < r["polynomial_e_aver_mm"], r
    twisting = [r for r in rows if r["mode"] == "twisting"]
    # the 4-ply twist sweeps show hysteresis well above the sensor noise: the thesis's >= 5x holds
    assert all(r["ratio"] >= 5 for r in twisting), twisting
