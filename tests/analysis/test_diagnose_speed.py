"""Diagnose on a long cycling run (250 lifetime cycles, ~45k samples, more motor stops than
the calibration subsample can keep) still names the hidden wear.

The lifetime run's speed (596 cycles, ~100k samples, <= 60 s) is measured by
scripts/bench/diagnose_speed.py, not asserted here."""

from __future__ import annotations

from tests.analysis import hidden
from tsa_bench.analysis import diagnose, load_model
from tsa_bench.sim.history import simulate
from tsa_bench.store import read_run


def test_long_cycling_run_names_resistance_creep(tmp_path):
    steps = [("load", 550), ("move", 15, 3.33), ("hold", 120)]
    for _ in range(250):
        for x in (17, 19, 21, 23, 25, 23, 21, 19, 17, 15):
            steps += [("move", x, 3.33, "cycle"), ("hold", 1.0, "cycle")]
    steps += [("move", 0, 3.33), ("hold", 30)]
    h = hidden.history(steps, 550)
    assert len(h["t"]) > 40_000
    cfg, _ = hidden.truth_config(("resistance_creep",), 1, h)
    out = simulate(cfg, h["t"], h["turns"], h["heater_voltage"], h["load_g"], h["motor_moving"].astype(bool), seed=1)
    path = hidden.write_run(tmp_path / "life.h5", h, out["length_mm"], out["resistance_ohm"])
    result = diagnose([read_run(path)], load_model(None), max_causes=1)
    assert result.verdict == "named" and result.causes == ["resistance_creep"], result.summary
    assert result.named[0].variant == "resistance_creep"      # with twist travel, not with time
    assert {g.output: g.relative for g in result.gain}["resistance"] >= 0.30
