"""What the user declares at import: a hanging load, constants, sign, offset, scale and calibration, and a word on
values no rig measures (issue 29, items 3 and 4)."""

from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from tests.importers.fixtures import run_import
from tsa_bench.cli import main
from tsa_bench.store import read_run

G0 = 9.80665


def _twist_csv(n: int = 120) -> str:
    """A twist staircase: holds of 2 s at 10 Hz, length shortening with twist."""
    rows = ["t [s],turns [turn],length [mm]"]
    for k in range(n):
        turns = (k // 20) * 2.0
        rows.append(f"{k * 0.1:.1f},{turns:g},{250 - 0.9 * turns - 0.01 * (k % 3):.3f}")
    return "\n".join(rows) + "\n"


def test_load_g_declares_the_hanging_load_and_fit_selects_by_it(tmp_path):
    res, out = run_import(tmp_path, _twist_csv(), "--load-g", "200")
    assert res.exit_code == 0, res.output
    run = read_run(out)
    assert np.allclose(run.samples["load"], 0.2 * G0)
    assert "load = 200g for every row (1.96133 N; --const)" in res.output
    assert json.loads(run.attrs["metadata"])["constants"] == {"load": "200g"}
    fit = CliRunner().invoke(main, ["fit", "polynomial", str(out), "--load-g", "200", "--out", str(tmp_path / "m.json")])
    assert fit.exit_code == 0, fit.output
    other = CliRunner().invoke(main, ["fit", "polynomial", str(out), "--load-g", "300", "--out", str(tmp_path / "n.json")])
    assert other.exit_code == 2 and "no samples at a load of 300 g (loads: 200 g)" in other.output


def test_const_takes_a_unit_and_refuses_a_column_already_there(tmp_path):
    res, out = run_import(tmp_path, _twist_csv(), "--const", "load=0.3kg,temperature=23degC")
    assert res.exit_code == 0, res.output
    run = read_run(out)
    assert np.allclose(run.samples["load"], 0.3 * G0) and np.allclose(run.samples["temperature"], 23.0)
    assert run.units["temperature"] == "degC"
    res, out = run_import(tmp_path, None, "--const", "length=100mm", out="b.h5")
    assert res.exit_code == 2 and not out.exists() and "length already comes from a source column" in res.output
    res, out = run_import(tmp_path, None, "--load-g", "200", "--const", "load=1N", out="c.h5")
    assert res.exit_code == 2 and not out.exists() and "both declare the load" in res.output


def test_fit_load_g_on_a_run_without_load_says_it_declares_none(tmp_path):
    res, out = run_import(tmp_path, _twist_csv())
    assert res.exit_code == 0, res.output
    fit = CliRunner().invoke(main, ["fit", "polynomial", str(out), "--load-g", "200", "--out", str(tmp_path / "m.json")])
    assert fit.exit_code == 2 and "this run declares no load" in fit.output and "(loads: )" not in fit.output
    assert "tsa-bench import --load-g" in fit.output


STAGE = "t [s],length [mm],resistance [ohm]\n" + "".join(
    f"{k * 0.1:.1f},{-12 + 0.1 * k:.2f},{-(5 + 0.01 * k):.3f}\n" for k in range(120))


def test_impossible_values_are_named_with_the_option_that_fixes_them(tmp_path):
    res, out = run_import(tmp_path, STAGE)
    assert res.exit_code == 0, res.output   # imported as asked, but not silently
    assert "warning: length is negative (120 rows, -12 to -0.1 mm)" in res.output
    assert "--negate length and/or --offset length=L0" in res.output
    assert "warning: resistance is negative (120 rows, -6.19 to -5 ohm)" in res.output and "--negate resistance" in res.output
    assert json.loads(read_run(out).attrs["metadata"])["import_warnings"]


def test_negate_and_offset_make_a_stage_position_a_length(tmp_path):
    res, out = run_import(tmp_path, STAGE, "--negate", "length,resistance", "--offset", "length=250")
    assert res.exit_code == 0, res.output
    assert "warning" not in res.output
    s = read_run(out).samples
    assert np.isclose(s["length"][0], 262.0) and np.isclose(s["length"][-1], 250.1)
    assert np.isclose(s["resistance"][0], 5.0)
    assert "length: negated, then +250 mm" in res.output
    res, out = run_import(tmp_path, None, "--negate", "length", "--offset", "length=25cm", "--scale", "resistance=-1",
                          out="b.h5")
    assert res.exit_code == 0, res.output
    s = read_run(out).samples
    assert np.isclose(s["length"][0], 262.0) and np.isclose(s["resistance"][0], 5.0)


def test_a_resistance_below_the_wires_is_named_as_a_likely_unit_error(tmp_path):
    res, out = run_import(tmp_path, "t [s],length [mm],R [ohm]\n0,100,0.0015\n0.1,100.1,0.0016\n")
    assert res.exit_code == 0
    assert "resistance below 0.1 ohm (2 rows, 0.0015 to 0.0016 ohm)" in res.output and "--units resistance=kohm" in res.output
    res, out = run_import(tmp_path, None, "--scale", "R=1e6", out="b.h5")
    assert res.exit_code == 0 and "warning" not in res.output and np.isclose(read_run(out).samples["resistance"][0], 1500)


def test_a_transducer_voltage_is_named_and_calibrated_into_a_length(tmp_path):
    text = "Time [s],Voltage [V]\n0,1.0\n0.1,1.2\n0.2,1.4\n"
    res, out = run_import(tmp_path, text)
    assert res.exit_code == 0, res.output
    assert "column 'Voltage [V]' is taken as the measured voltage by its name alone" in res.output
    assert "--map length=Voltage --scale length=2.5mm/V" in res.output
    res, out = run_import(tmp_path, None, "--map", "length=Voltage", "--scale", "length=2.5mm/V", out="b.h5")
    assert res.exit_code == 0, res.output
    assert np.allclose(read_run(out).samples["length"], [2.5, 3.0, 3.5])
    assert "[V x 2.5 mm/V -> mm, x2.5]" in res.output
    res, out = run_import(tmp_path, None, "--map", "length=Voltage", "--scale", "length=2.5ohm/V", out="c.h5")
    assert res.exit_code == 2 and not out.exists() and "V x ohm/V is resistance, not length" in res.output
