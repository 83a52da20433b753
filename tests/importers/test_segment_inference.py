"""Segment inference with a minimum duration and hysteresis around each threshold (issue 29, items 2 and 5).

The data are written here as a logger would record them (a twist sampled at 20 Hz held in a 90 Hz log, a heater
staircase printed with two decimals); nothing here calls the inference's own helpers."""

from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from tests.importers.fixtures import run_import
from tsa_bench.cli import main
from tsa_bench.store import read_run


def _cycles_sample_held() -> str:
    """9 twist cycles (up 3 s, hold 2 s, down 3 s, hold 2 s) of an angle read at 20 Hz, logged at 90 Hz."""
    t = np.arange(0, 90.0, 1 / 90)
    held = np.floor(t * 20) / 20                    # the angle sensor's own clock: its value is held between reads
    phase = held % 10.0
    turns = np.select([phase < 3, phase < 5, phase < 8], [phase / 3 * 6, 6.0, (8 - phase) / 3 * 6], 0.0)
    length = 250 - 0.9 * turns
    return "t [s],turns [turn],length [mm]\n" + "".join(f"{a:.4f},{b:.4f},{c:.4f}\n" for a, b, c in zip(t, turns, length))


def test_a_twist_held_between_reads_gives_one_move_per_sweep(tmp_path):
    res, out = run_import(tmp_path, _cycles_sample_held())
    assert res.exit_code == 0, res.output
    run = read_run(out)
    kinds = list(run.segments["kind"].astype(str))
    assert kinds.count("move") == 18, kinds[:12]             # up and down in each of 9 cycles, not one per read
    assert kinds.count("hold") in (18, 19)
    seg, moving = run.samples["segment"], run.samples["motor_moving"].astype(bool)
    for k in np.flatnonzero(run.segments["kind"].astype(str) == "move"):
        assert moving[seg == k].all()                        # the rows between two reads are part of the move
    durations = run.segments["t_end"] - run.segments["t_start"]
    assert durations[1:-1].min() >= 0.25                      # the first hold ends at the first read (0.05 s)
    assert "minimum duration 0.25 s" in res.output


def _staircase(levels: int = 60, hold_rows: int = 10) -> str:
    """A heater staircase of 0.05 V steps (exactly the default threshold), each held 1 s at 10 Hz, as %.2f."""
    rows = ["t [s],heater_voltage [V],length [mm]"]
    for k in range(levels * hold_rows):
        v = (k // hold_rows) * 0.05
        rows.append(f"{k * 0.1:.1f},{v:.2f},{250 - 3 * v:.3f}")
    return "\n".join(rows) + "\n"


def test_a_staircase_of_exactly_the_threshold_gives_one_segment_per_level(tmp_path):
    res, out = run_import(tmp_path, _staircase())
    assert res.exit_code == 0, res.output
    run = read_run(out)
    assert len(run.segments) == 60
    v, seg = run.samples["heater_voltage"], run.samples["segment"]
    spans = [np.ptp(v[seg == k]) for k in range(len(run.segments))]
    assert max(spans) < 1e-9                                # no segment spans two levels
    assert "heater 0.05 V (hysteresis 0.01)" in res.output


def test_spikes_on_the_threshold_edge_open_no_segment_but_a_held_step_does(tmp_path):
    rng = np.random.default_rng(3)
    n = 400
    v = np.full(n, 1.0) + rng.uniform(-0.015, 0.015, n)      # noise well inside the band
    v[[50, 120, 121, 300]] += 0.05                           # one- and two-row spikes of exactly the threshold
    v[[80, 250]] += 0.3                                      # and two far beyond it
    v[200:] += 0.2                                           # one real step, held
    text = "t [s],heater_voltage [V],length [mm]\n" + "".join(f"{k * 0.1:.1f},{x:.4f},100\n" for k, x in enumerate(v))
    res, out = run_import(tmp_path, text)
    assert res.exit_code == 0, res.output
    run = read_run(out)
    assert list(run.segments["kind"].astype(str)) == ["hold", "heater"]
    assert np.isclose(run.segments["t_start"][1], 20.0)


def test_a_level_passed_through_in_less_than_the_minimum_duration_is_no_segment(tmp_path):
    volts = [0.0] * 30 + [1.0] * 2 + [2.0] * 30            # 1 V for 0.2 s on the way from 0 to 2 V
    text = "t [s],heater_voltage [V],length [mm]\n" + "".join(f"{k * 0.1:.1f},{v:g},100\n" for k, v in enumerate(volts))
    res, out = run_import(tmp_path, text)
    assert res.exit_code == 0, res.output
    run = read_run(out)
    assert list(run.segments["kind"].astype(str)) == ["hold", "heater"]
    assert np.isclose(run.segments["t_start"][1], 3.2)       # the 2 V level; the 1 V rows stay with the 0 V hold


def test_the_settings_are_overridable_checked_and_stored(tmp_path):
    res, out = run_import(tmp_path, _staircase(), "--segment-threshold", "heater_V=0.1,heater_hyst_V=0.02,min_s=2")
    assert res.exit_code == 0, res.output
    assert "heater 0.1 V (hysteresis 0.02)" in res.output and "minimum duration 2 s" in res.output
    meta = json.loads(read_run(out).attrs["metadata"])["segments"]["thresholds"]
    assert meta["heater_V"] == 0.1 and meta["heater_hyst_V"] == 0.02 and meta["min_s"] == 2
    assert len(read_run(out).segments) < 60                  # levels of 1 s are shorter than 2 s: merged
    bad, out = run_import(tmp_path, None, "--segment-threshold", "heater_V=0.05,heater_hyst_V=0.05", out="b.h5")
    assert bad.exit_code == 2 and not out.exists() and "heater_hyst_V=0.05 (must be below heater_V=0.05)" in bad.output


def test_a_heater_run_without_twist_fits_on_its_heater_segments(tmp_path):
    """An SMA wing's data: voltage in, deflection out, no twist; the default import infers heater segments."""
    rows = ["t [s],heater_voltage [V],length [mm]"]
    levels = [0.0, 1.0, 2.0, 3.0, 2.0, 1.0, 0.0, 1.5, 3.0, 1.5, 0.0]
    for k in range(len(levels) * 40):
        v = levels[k // 40]
        rows.append(f"{k * 0.1:.1f},{v:g},{100 - 4 * np.tanh(v - 1.5) - (0.3 if k // 40 >= 4 else 0):.4f}")
    res, out = run_import(tmp_path, "\n".join(rows) + "\n")
    assert res.exit_code == 0, res.output
    assert "heater" in set(read_run(out).segments["kind"].astype(str))
    fit = CliRunner().invoke(main, ["fit", "preisach", str(out), "--input", "heater_voltage", "--output", "length",
                                    "--levels", "6", "--out", str(tmp_path / "m.json")])
    assert fit.exit_code == 0, fit.output
    assert "has no finite samples" not in fit.output
    n = json.loads((tmp_path / "m.json").read_text())["metrics"]["identification"][str(out)]["n"]
    assert 0.25 * 440 < n < 0.5 * 440                         # the last third of each heater segment


def test_a_noisy_measured_twist_keeps_its_state_inside_the_hysteresis_band(tmp_path):
    """A measured (noisy) twist: holds jitter by up to 0.008 turn per row, moves slow down to 0.008 turn per row
    every third row. Threshold 0.01 with hysteresis 0.005 (moving above 0.015, still at or below 0.005)
    keeps each move whole; min_s=0 so that only the hysteresis decides."""
    rng = np.random.default_rng(5)
    pos, turns = 0.0, []
    for move in range(4):
        turns += list(pos + rng.uniform(-0.004, 0.004, 30))                     # hold
        for k in range(30):
            pos += 0.008 if k % 3 == 2 else 0.05
            turns.append(pos)
    turns += list(pos + rng.uniform(-0.004, 0.004, 30))
    text = "t [s],turns [turn],length [mm]\n" + "".join(f"{k * 0.1:.1f},{v:.5f},100\n" for k, v in enumerate(turns))
    res, out = run_import(tmp_path, text, "--segment-threshold", "turns=0.01,turns_hyst=0.005,min_s=0")
    assert res.exit_code == 0, res.output
    kinds = list(read_run(out).segments["kind"].astype(str))
    assert kinds.count("move") == 4 and kinds.count("hold") == 5
