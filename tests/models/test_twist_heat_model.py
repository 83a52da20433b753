"""The joint length model of twist and heater voltage: the coupled form's gain over the thesis's
additive eq. 3.3 on held-out data, on the simulated plant and on an independent generator."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.models.saved import load_model_file
from tsa_bench.models.twist_heat import ADDITIVE, COUPLED, TERMS, TwistHeatModel

ROOT = Path(__file__).resolve().parents[2]
PROTOCOLS = ROOT / "configs" / "protocols"
BENCH = ROOT / "configs" / "bench" / "sim-4ply.yaml"


# -- an independent generator: numpy only, its own coupling form and constants ----------------
def _generate(turns: np.ndarray, volts: np.ndarray, coupling: float, rng: np.random.Generator) -> np.ndarray:
    """Quasi-static length (mm): twist shortens quadratically, heating contracts by a saturating
    exp(-V^2) law whose depth grows linearly with twist when ``coupling`` > 0; noise 0.3 mm."""
    twist_part = 410.0 - 0.021 * turns ** 2 - 0.3 * turns
    heat_depth = 31.0 * (1.0 + coupling * turns / 90.0)
    heat_part = -heat_depth * (1.0 - np.exp(-(volts / 7.0) ** 2))
    return twist_part + heat_part + rng.normal(0.0, 0.3, turns.shape)


def _grid_and_diagonal(coupling: float, seed: int):
    rng = np.random.default_rng(seed)
    t_train, v_train = (a.ravel() for a in np.meshgrid(np.repeat([0.0, 30.0, 60.0, 90.0], 40),
                                                       [0.0, 2.5, 5.0, 7.5, 10.0]))
    k = np.repeat(np.arange(10.0), 40)
    t_test = np.concatenate([9.0 * k + 4.0, 9.0 * k + 4.0])
    v_test = np.concatenate([k, 9.5 - k])       # rising and falling with the twist: never on the grid
    return (t_train, v_train, _generate(t_train, v_train, coupling, rng),
            t_test, v_test, _generate(t_test, v_test, coupling, rng))


def _held_out_rmse(coupling: float, seed: int) -> dict[str, float]:
    t, v, y, tt, vt, yt = _grid_and_diagonal(coupling, seed)
    out = {}
    for name in (ADDITIVE, COUPLED):
        model = TwistHeatModel.fit(t, v, y, TERMS[name])
        out[name] = float(np.sqrt(np.mean((model.predict(tt, vt) - yt) ** 2)))
    return out


@pytest.mark.parametrize("seed", [0, 1])
def test_on_coupled_generated_data_the_coupled_form_halves_the_held_out_error(seed):
    rmse = _held_out_rmse(coupling=0.6, seed=seed)
    assert rmse[COUPLED] < 0.5 * rmse[ADDITIVE], rmse
    assert rmse[ADDITIVE] > 1.0, rmse      # the additive form really misses the coupling


@pytest.mark.parametrize("seed", [0, 1])
def test_on_uncoupled_generated_data_the_coupled_form_claims_no_gain(seed):
    rmse = _held_out_rmse(coupling=0.0, seed=seed)
    assert abs(1.0 - rmse[COUPLED] / rmse[ADDITIVE]) < 0.05, rmse
    assert rmse[COUPLED] < 0.6, rmse          # both near the generator's 0.3 mm noise (plus fit error)


def test_fitted_coefficients_are_those_of_an_exact_polynomial():
    t, v = (a.ravel() for a in np.meshgrid(np.linspace(0, 80, 9), np.linspace(0, 8, 9)))
    truth = TwistHeatModel(TERMS[COUPLED], (300.0, -0.2, -0.01, 1e-5, -1.0, -0.3, 0.01, -0.02, -1e-4, 3e-3))
    fitted = TwistHeatModel.fit(t, v, truth.predict(t, v), TERMS[COUPLED])
    assert np.allclose(fitted.coefficients, truth.coefficients, rtol=1e-6, atol=1e-9)


# -- on the simulated plant, through the CLI ------------------------------------------------------
@pytest.fixture(scope="module")
def plant_runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("twist-heat")
    out = {}
    for name, protocol, seed in (("train", "twist-heat-grid", 1), ("held", "twist-heat-simultaneous", 2)):
        path = d / f"{name}.h5"
        res = CliRunner().invoke(main, ["run", str(PROTOCOLS / f"{protocol}.yaml"), "--bench", str(BENCH),
                                        "--seed", str(seed), "--output", str(path)])
        assert res.exit_code == 0, res.output
        out[name] = str(path)
    out["dir"] = d
    return out


def test_on_the_plant_the_coupled_form_beats_the_thesis_additive_form_on_held_out_runs(plant_runs):
    rmse = {}
    for name in (ADDITIVE, COUPLED):
        model = plant_runs["dir"] / f"{name}.json"
        res = CliRunner().invoke(main, ["fit", name, plant_runs["train"], "--validate", plant_runs["held"],
                                        "--out", str(model)])
        assert res.exit_code == 0, res.output
        saved = load_model_file(model)
        assert saved.input == {"column": "turns+heater_voltage", "unit": "turn, V"}
        assert saved.options["voltage_range_V"] == pytest.approx([0.0, 8.0], abs=0.01)  # the PWM duty rounding
        assert saved.options["turns_range"] == [0.0, 81.0]
        rmse[name] = saved.metrics["validation"][plant_runs["held"]]["rmse"]
        assert saved.metrics["validation"][plant_runs["held"]]["n"] > 5000
    coupled = json.loads((plant_runs["dir"] / f"{COUPLED}.json").read_text())["parameters"]
    assert coupled["c_T2_V1"]["unit"] == "mm/(turn^2 V)" and coupled["c_T0_V0"]["unit"] == "mm"
    # the plant's length noise is 0.51 mm (sd): the coupled form gets near it, the additive one does not
    assert rmse[COUPLED] < 0.7 * rmse[ADDITIVE] and rmse[COUPLED] < 0.8, rmse
    res = CliRunner().invoke(main, ["predict", str(plant_runs["dir"] / f"{COUPLED}.json"), plant_runs["held"]])
    assert res.exit_code == 0 and "prediction" in res.output, res.output


def test_bad_input_is_refused_with_the_reason(plant_runs, tmp_path):
    res = CliRunner().invoke(main, ["fit", COUPLED, plant_runs["train"], "--input", "turns", "--out",
                                    str(tmp_path / "m.json")])
    assert res.exit_code == 2 and "do not apply" in res.output and not (tmp_path / "m.json").exists()
    # a run that never heats cannot identify a voltage dependence
    plain = tmp_path / "plain.h5"
    assert CliRunner().invoke(main, ["run", str(PROTOCOLS / "twist-sweep-4ply.yaml"), "--bench", str(BENCH),
                                     "--output", str(plain)]).exit_code == 0
    res = CliRunner().invoke(main, ["fit", COUPLED, str(plain), "--out", str(tmp_path / "m.json")])
    assert res.exit_code == 2 and "more than one heater voltage" in res.output, res.output
