"""The point runners called directly (no cluster): what each one computes from its configuration."""

from __future__ import annotations

import math

from tsa_bench.sweep import load_study
from tsa_bench.sweep.points import run_point


def points(tmp_path, text):
    p = tmp_path / "s.yaml"
    p.write_text(text, encoding="utf-8")
    s = load_study(p)
    return s, [run_point(s.runner, pt.key, pt.config) for pt in s.points]


def test_diagnose_runner_names_a_strong_hidden_effect_and_explains_a_clean_run(tmp_path):
    s, rows = points(tmp_path, """\
study: d
runner: diagnose
base: {protocol: {hold_s: 10.0, repeats: 1}}
vary:
  effect.name: [resistance_transient_decay]
  effect.magnitude: [0, 1.0]
""")
    assert [r["status"] for r in rows] == ["done", "done"], rows
    clean, hidden = (r["figures"] for r in rows)
    assert clean["verdict"] == "explained" and clean["alarm"] is False and clean["detected"] is None
    assert hidden["verdict"] == "named" and hidden["causes"] == "resistance_transient_decay"
    assert hidden["detected"] is True and hidden["alarm"] is True
    assert 3 < hidden["run_length_min"] < 10


def test_fit_runner_scores_on_the_validation_staircase(tmp_path):
    s, rows = points(tmp_path, """\
study: f
runner: fit
base: {protocol: {hold_s: 2.0, cycles: 1, rest_s: 10.0}, fit: {validate_hold_s: 3.0, validate_cycles: 1}}
vary:
  fit.model: [polynomial, strain-resistance]
""")
    poly, sr = (r["figures"] for r in rows)
    assert 0 < poly["validation_e_aver_mm"] < 1.0 and 0 < poly["identification_e_aver_mm"] < 1.0
    assert 0 < sr["validation_e_aver_ohm"] < 0.5 and "validation_e_aver_mm" not in sr
    assert math.isfinite(poly["validation_mean_percent"])


def test_reproduce_runner_gives_a_record_verdict(tmp_path):
    s, rows = points(tmp_path, """\
study: r
runner: reproduce
vary:
  reproduce.record: [ch2.scheme1.length_20turns]
""")
    f = rows[0]["figures"]
    assert f["unit"] == "cm" and f["verdict"] == "agrees" and f["agrees"] is True and abs(f["gap_percent"]) < 10


def test_simulate_runner_measures_the_creep_it_is_given(tmp_path):
    s, rows = points(tmp_path, """\
study: c
runner: simulate
base: {protocol: {cycles: 30}, bench: {settle_s: 10}}
vary:
  plant.effects.resistance_creep.ohm_per_turn: [1.0e-3]
""")
    f = rows[0]["figures"]
    # 20 turns of travel per cycle of about 17 s: 1e-3 ohm/turn is about 4 ohm/h
    assert 3.0 < f["drift_ohm_per_h"] < 5.5 and f["drift_detected"] is True and f["drift_holds"] == 30   # one per cycle; the rest left out
