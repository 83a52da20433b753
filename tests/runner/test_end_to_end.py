"""Every shipped protocol end to end on the simulated bench: contract and physics."""

from __future__ import annotations

import functools
import json
import tempfile
from pathlib import Path

import h5py
import numpy as np
import pytest
from scipy.stats import spearmanr

from tests.runner.helpers import run_plan, shipped_plan
from tsa_bench.store import read_run

PROTOCOLS = sorted(p.name for p in (Path(__file__).resolve().parents[2] / "configs" / "protocols").glob("*.yaml"))
REQUIRED = {"t": "s", "turns": "turn", "length": "mm", "resistance": "ohm", "heater_voltage": "V", "load": "N",
            "segment": "1", "motor_moving": "1"}


@functools.lru_cache(maxsize=None)
def run_shipped(name: str):
    """Run one shipped protocol once per session; return what the tests inspect."""
    plan = shipped_plan(name)
    bench = None
    if "bench" in plan.metadata:  # a protocol for one string names its simulated preset
        from tsa_bench.bench import load_bench
        from tsa_bench.shipped import shipped

        bench = load_bench(shipped(f"bench/{plan.metadata['bench']}.yaml"))
    stop, client, path = run_plan(plan, Path(tempfile.mkdtemp(prefix=name.removesuffix(".yaml"))), bench=bench)
    with h5py.File(path, "r") as f:
        data = {name: ds[()] for name, ds in f["samples"].items()}
        units = {name: ds.attrs["units"] for name, ds in f["samples"].items()}
        attrs = dict(f.attrs)
        config = f["config/protocol"][()].decode()
    segs = read_run(path).segments   # texts in every row, whichever layout the file has
    return plan, stop, data, units, segs, attrs, config


@pytest.fixture(params=PROTOCOLS)
def finished_run(request):
    return run_shipped(request.param)


def test_run_succeeds_and_meets_the_contract(finished_run):
    plan, stop, data, units, segs, attrs, config = finished_run
    assert stop.exit_status == "success", stop.reason
    assert attrs["exit_status"] == "success" and attrs["format"] == "tsa-bench/run" and attrs["backend"] == "sim"
    assert config == plan.source_text
    for name, unit in REQUIRED.items():
        assert units[name] == unit
    assert len({len(v) for v in data.values()}) == 1, "all sample columns have equal length"
    assert len(data["t"]) > 10 and np.all(np.diff(data["t"]) > 0)
    assert stop.samples_lost == 0 and np.all(np.diff(data["counter"].astype(np.int64)) == 1)


def test_segments_match_the_plan(finished_run):
    plan, stop, data, units, segs, attrs, config = finished_run
    assert list(segs["index"]) == list(range(len(plan.segments)))
    assert [k.decode() for k in segs["kind"]] == [s.kind for s in plan.segments]
    assert segs["completed"].all()
    assert np.all(segs["t_end"] >= segs["t_start"]) and np.all(np.diff(segs["t_start"]) >= 0)
    for seg, row in zip(plan.segments[:50], segs[:50]):
        stored = json.loads(row["params"])
        if seg.kind == "settle":  # what the settling hold found is added to its parameters
            assert set(stored) - set(seg.params()) == {"settled", "dR_dt_ohm_per_s", "dL_dt_mm_per_s"}
            stored = {k: v for k, v in stored.items() if k in seg.params()}
        if seg.kind == "track_length":  # and what the controller did
            assert set(stored) - set(seg.params()) == {"targets_reached", "targets", "final_mm_per_turn"}
            stored = {k: v for k, v in stored.items() if k in seg.params()}
        assert stored == json.loads(json.dumps(seg.params()))
    holds = segs[[k == b"hold" for k in segs["kind"]]]
    durations = [json.loads(p)["duration_s"] for p in holds["params"]]
    assert np.allclose(holds["t_end"] - holds["t_start"], durations, atol=1e-5)
    # samples point at the segment that was executing
    seg_of_sample = data["segment"]
    assert seg_of_sample.min() >= -1 and seg_of_sample.max() < len(plan.segments)
    # a settling hold ends between its minimum and maximum; the plan's estimate counts the maximum
    settles = segs[[k == b"settle" for k in segs["kind"]]]
    spent = settles["t_end"] - settles["t_start"]
    limits = [json.loads(p) for p in settles["params"]]
    assert all(d["min_duration_s"] - 1e-5 <= x <= d["max_duration_s"] + 1e-5 for d, x in zip(limits, spent))
    saved = sum(d["max_duration_s"] for d in limits) - float(spent.sum())
    tracks = segs[[k == b"track_length" for k in segs["kind"]]]   # the plan counts every timeout
    saved += sum(s.action.longest_s for s in plan.segments if s.kind == "track_length") \
        - float((tracks["t_end"] - tracks["t_start"]).sum())
    expected = plan.summary().duration_s - saved
    assert abs(stop.t_end - expected) < 0.02 * expected + 5


def _settled(values: np.ndarray, held: np.ndarray) -> np.ndarray:
    """The values of the last quarter of each contiguous stretch where ``held`` is true."""
    idx = np.flatnonzero(held)
    stretches = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)
    return np.concatenate([values[s[len(s) - max(1, len(s) // 4):]] for s in stretches])


def test_physical_sanity(finished_run):
    plan, stop, data, units, segs, attrs, config = finished_run
    cold = (data["heater_voltage"] == 0) & (data["motor_moving"] == 0)
    # twist levels held in staircases; a track_length reaches its twists from both sides
    # with corrections of a fraction of a turn, where twist hysteresis exceeds the 0.5 mm below
    tracked = [s.index for s in plan.segments if s.kind == "track_length"]
    cold &= ~np.isin(data["segment"], tracked)
    for load in np.unique(data["load"]):
        sel = cold & (data["load"] == load)
        turns, length, resistance = data["turns"][sel], data["length"][sel], data["resistance"][sel]
        if sel.any() and np.ptp(turns) >= 5:
            # per twist level held: length never rises with twist (beyond noise), and falls overall.
            # A level's length is the settled one: the last quarter of each stretch held there
            # (the first hold follows the hanging of the load, whose creep is still under way
            # in its first minutes; a level held after heating is still cooling).
            levels = np.unique(np.round(turns, 3))
            all_turns = np.round(data["turns"], 3)
            median_length = np.array([np.median(_settled(data["length"], sel & (all_turns == lv))) for lv in levels])
            assert np.all(np.diff(median_length) < 0.5), f"length rises with twist (load {load:.2f} N)"
            assert median_length[0] - median_length[-1] > 5, f"length falls as twist rises (load {load:.2f} N)"
            # resistance follows length wherever length still changes (past full twist it cannot)
            median_r = np.array([np.nanmedian(resistance[np.round(turns, 3) == lv]) for lv in levels])
            moving = np.concatenate([[True], np.abs(np.diff(median_length)) > 2.0])
            if moving.sum() >= 3:
                rho = spearmanr(median_length[moving], median_r[moving])[0]
                assert rho > 0.8, f"resistance follows length (load {load:.2f} N)"
    loads = np.unique(data["load"])
    if len(loads) > 1:
        untwisted = cold & (np.abs(data["turns"]) < 1e-9)
        means = [data["length"][untwisted & (data["load"] == w)].mean() for w in loads
                 if (untwisted & (data["load"] == w)).any()]
        if len(means) > 1:
            assert np.all(np.diff(means) > 0), "a heavier load stretches the compliant strings"
    heated = data["heater_voltage"] > 0
    assert np.all(np.isnan(data["resistance"][heated])), "no resistance while heating"
    assert np.all(np.isfinite(data["resistance"][~heated]))


def test_lifetime_has_all_cycles():
    plan, stop, data, units, segs, attrs, config = run_shipped("lifetime.yaml")
    assert len(np.unique(segs["cycle"][segs["cycle"] >= 0])) == 596
    assert data["t"][-1] > 2.5 * 3600
