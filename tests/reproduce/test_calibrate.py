"""Calibration pieces: residuals agree with verdicts, fitted values are written back without touching the rest."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from tsa_bench.reproduce.calibrate import (Settings, load_settings, run_fit, write_flow_value, write_plant_value)
from tsa_bench.reproduce.plan import Fit
from tsa_bench.reproduce.records import Record, load_records
from tsa_bench.reproduce.table import judge, residual

ROOT = Path(__file__).resolve().parents[2]


def _rec(value=10.0, relation="=", rng=None, tolerance=None, uncertainty=None) -> Record:
    return Record(id="x", quantity="q", unit="mm", value=None if rng else value, range=rng, relation=relation,
                  conditions={}, source={"section": "1"}, file="f", line=1, chapter=2,
                  uncertainty=uncertainty or {}, tolerance=tolerance or {}, measure={"name": "scheme_length"})


RECORDS = [
    _rec(tolerance={"kind": "abs", "value": 0.5, "basis": "b"}),
    _rec(tolerance={"kind": "rel", "value": 0.1, "basis": "b"}),
    _rec(tolerance={"kind": "factor", "value": 2.0, "basis": "b"}),
    _rec(tolerance={"kind": "sd", "value": 3.0, "basis": "b"}),
    _rec(uncertainty={"rounding": 0.05}),
    _rec(relation=">"), _rec(relation="<"), _rec(relation="<="), _rec(relation=">="),
    _rec(rng=(2.0, 3.0)),
]


@settings(max_examples=300, deadline=None)
@given(i=st.integers(0, len(RECORDS) - 1), sim=st.floats(-50, 50, allow_nan=False))
def test_residual_within_one_exactly_when_the_record_agrees(i, sim):
    rec = RECORDS[i]
    assert judge(rec, sim) == (abs(residual(rec, sim)) <= 1.0)


def test_residual_examples():
    assert residual(RECORDS[0], 11.0) == pytest.approx(2.0)
    assert residual(RECORDS[2], 20.0) == pytest.approx(1.0) and residual(RECORDS[2], 5.0) == pytest.approx(-1.0)
    assert residual(RECORDS[2], -10.0) >= 1e3  # wrong sign never agrees within a factor
    # a subnormal simulated value: sim / value underflows to 0, the residual is still finite and far out
    tiny = residual(RECORDS[2], 5e-324)
    assert math.isfinite(tiny) and tiny < -1.0 and not judge(RECORDS[2], 5e-324)
    assert residual(RECORDS[5], 11.0) == 0.0 and residual(RECORDS[5], 9.0) < -1.0
    assert residual(RECORDS[9], 2.5) == 0.0 and residual(RECORDS[9], 3.5) > 1.0


def test_writing_a_fitted_value_changes_only_that_line(tmp_path):
    text = (ROOT / "configs" / "bench" / "sim-scheme1.yaml").read_text()
    new = write_plant_value(text, "effects.string_compliance.stiffness_N", 1234.5)
    new = write_plant_value(new, "effects.length_settling.hold_sd_mm", 0.25)
    new = write_plant_value(new, "radius_mm", 0.5)
    new = write_plant_value(new, "effects.warp_effect.lightyears", 2.0)  # a block that did not exist
    a, b = yaml.safe_load(text), yaml.safe_load(new)
    assert b["plant"]["effects"]["string_compliance"]["stiffness_N"] == 1234.5
    assert b["plant"]["effects"]["length_settling"]["hold_sd_mm"] == 0.25 and b["plant"]["radius_mm"] == 0.5
    assert b["plant"]["effects"]["warp_effect"] == {"lightyears": 2.0}
    b["plant"]["effects"]["string_compliance"]["stiffness_N"] = a["plant"]["effects"]["string_compliance"]["stiffness_N"]
    b["plant"]["effects"]["length_settling"]["hold_sd_mm"] = a["plant"]["effects"]["length_settling"]["hold_sd_mm"]
    b["plant"]["radius_mm"] = a["plant"]["radius_mm"]
    del b["plant"]["effects"]["warp_effect"]
    assert a == b  # nothing else changed
    kept = [ln for ln in text.splitlines() if "stiffness_N" not in ln and "hold_sd_mm" not in ln
            and "radius_mm" not in ln]
    assert all(ln in new.splitlines() for ln in kept)  # every other line and comment kept
    man = (ROOT / "configs" / "manipulator" / "thesis.yaml").read_text()
    out = write_flow_value(man, "control.motor_rev_per_s_per_V", 0.0812)
    assert yaml.safe_load(out)["control"]["motor_rev_per_s_per_V"] == 0.0812
    assert yaml.safe_load(out)["geometry"] == yaml.safe_load(man)["geometry"]


def test_a_fit_moves_its_parameter_to_match_its_record():
    records = load_records()
    start = load_settings()
    start.set("manipulator", "control.motor_rev_per_s_per_V", 0.5)
    fit = Fit("motor", {(("manipulator",), "control.motor_rev_per_s_per_V"): (0.02, 0.6)}, ["ch4.control.rise_time"])
    out, res = run_fit(fit, records, start, maxfev=25)
    assert isinstance(out, Settings)
    assert abs(res.residuals["ch4.control.rise_time"]) <= 1.0 < abs(res.cost_start)
    assert res.values[(("manipulator",), "control.motor_rev_per_s_per_V")] < 0.2  # 8 s needs a slow motor
    assert start.get("manipulator", "control.motor_rev_per_s_per_V") == 0.5  # the input settings are not changed
