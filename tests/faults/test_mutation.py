"""Property-based mutation (hypothesis) of protocols, bench files, CSVs, model files and
run files: every command that reads them exits 0 or 2 and never with a traceback.
Then, one by one, the bad inputs the reliability review found.
(scripts/fuzz_inputs.py runs thousands of these across every command.)"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.faults.mutations import (
    CSV_OPS, JSON_OPS, RUN_OPS, TEXT_OPS, apply_csv, apply_json, apply_text, mutate_run, write_text,
)
from tsa_bench.cli import main
from tsa_bench.store import read_run

ROOT = Path(__file__).resolve().parents[2]
PROTOCOL = ROOT / "configs/protocols/transient-steps.yaml"
BENCH = ROOT / "configs/bench/sim-scheme1.yaml"
MUTATION = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def ops(kinds) -> st.SearchStrategy:
    return st.lists(st.tuples(st.sampled_from(kinds), st.integers(0, 10**6), st.integers(0, 10**6)),
                    min_size=1, max_size=3)


def invoke(*args: str, allowed=(0, 2)):
    res = CliRunner().invoke(main, list(args))
    assert res.exception is None or isinstance(res.exception, SystemExit), \
        f"{args}: {type(res.exception).__name__}: {res.exception}"
    assert res.exit_code in allowed, f"{args}: exit {res.exit_code}: {res.output[-400:]}"
    return res


SWEEP = """name: small sweep
load_g: 200
defaults: {rate_turns_per_s: 2, accel_turns_per_s2: 20}
steps:
  - rotation_sequence: {targets_turns: [5, 10, 15, 10, 5, 0], hold_s: 3}
"""


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    d = tmp_path_factory.mktemp("good")
    run = d / "good.h5"
    (d / "sweep.yaml").write_text(SWEEP)
    invoke("run", str(d / "sweep.yaml"), "--output", str(run), allowed=(0,))
    invoke("export", str(run), "--csv", "--out", str(d), allowed=(0,))
    invoke("fit", "polynomial", str(run), "--out", str(d / "m.json"), allowed=(0,))
    return {"run": run, "csv": d / "good.samples.csv", "model": d / "m.json"}


@MUTATION
@given(mutation=ops(TEXT_OPS))
def test_mutated_protocols_are_validated_cleanly(tmp_path, mutation):
    p = write_text(tmp_path / "p.yaml", apply_text(PROTOCOL.read_text(), mutation))
    invoke("validate", str(p))


@MUTATION
@given(mutation=ops(TEXT_OPS))
def test_mutated_bench_files_are_validated_cleanly(tmp_path, mutation):
    b = write_text(tmp_path / "b.yaml", apply_text(BENCH.read_text(), mutation))
    invoke("validate", str(PROTOCOL), "--bench", str(b))
    invoke("effects", "--bench", str(b))


@MUTATION
@given(mutation=ops(CSV_OPS))
def test_mutated_csvs_are_imported_cleanly(tmp_path, good, mutation):
    c = write_text(tmp_path / "c.csv", apply_csv(good["csv"].read_text(), mutation))
    out = tmp_path / "imported.h5"
    if out.exists():
        out.unlink()
    invoke("import", str(c), "--out", str(out))


@MUTATION
@given(mutation=ops(JSON_OPS))
def test_mutated_model_files_are_refused_cleanly(tmp_path, good, mutation):
    text = good["model"].read_text()
    m = write_text(tmp_path / "m.json", apply_json(json.loads(text), text, mutation))
    invoke("predict", str(m), str(good["run"]))


@MUTATION
@given(mutation=ops(RUN_OPS))
def test_mutated_run_files_are_read_cleanly(tmp_path, good, mutation):
    r = mutate_run(good["run"], tmp_path / "r.h5", mutation)
    invoke("info", str(r))
    invoke("export", str(r), "--csv", "--out", str(tmp_path / "csv"))
    invoke("watch", str(r), "--once", "--wait", "0", allowed=(0, 1, 2))
    invoke("fit", "polynomial", str(r), "--out", str(tmp_path / "m.json"))


# -- the review's findings, one by one ------------------------------------------------
def protocol(tmp_path, text: str) -> str:
    p = tmp_path / "p.yaml"
    write_text(p, text)
    return str(p)


BASE = "name: t\nsteps:\n  - move_to: {turns: 1, rate_turns_per_s: 1, accel_turns_per_s2: 10}\n"


@pytest.mark.parametrize("text, message", [
    ("a: &a [x,x,x,x,x,x,x,x,x]\nb: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]\nc: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b]\n"
     "d: &d [*c,*c,*c,*c,*c,*c,*c,*c,*c]\ne: &e [*d,*d,*d,*d,*d,*d,*d,*d,*d]\nf: &f [*e,*e,*e,*e,*e,*e,*e,*e,*e]\n"
     "g: [*f,*f,*f,*f,*f,*f,*f,*f,*f]\n" + BASE, "aliases expand"),
    (BASE + "metadata: {x: " + "[" * 3000 + "]" * 3000 + "}\n", "nested more than"),
    (BASE + "load_g: " + "9" * 4400 + "\n", "digits is too large"),
    ("name: t\nsteps:\n  - prompt: {text: \"hang \\ud800 g\"}\n", "lone surrogate"),
    (BASE + "load_g: 5000000\n", "load_g"),
    (BASE + "  - hold: {duration_s: 700000}\n", "7 days"),
])
def test_validate_refuses_with_a_position(tmp_path, text, message):
    path = protocol(tmp_path, text)
    res = invoke("validate", path, allowed=(2,))
    assert message in res.output and f"{path}:" in res.output, res.output
    res = invoke("run", path, "--output", str(tmp_path / "r.h5"), allowed=(2,))  # run refuses the same
    assert message in res.output and not (tmp_path / "r.h5").exists()


def test_a_hold_longer_than_one_dwell_runs_as_several(tmp_path):
    """DWELL carries at most 4294.967 s: a 10,000 s hold is sent as three DWELLs and
    recorded as one segment of exactly 10,000 s."""
    path = protocol(tmp_path, BASE + "  - hold: {duration_s: 10000}\n"
                              "  - move_to: {turns: 0, rate_turns_per_s: 1, accel_turns_per_s2: 10}\n")
    invoke("validate", path, allowed=(0,))
    out = tmp_path / "r.h5"
    invoke("run", path, "--output", str(out), allowed=(0,))
    seg = read_run(out).segments
    hold = seg[seg["kind"] == b"hold"][0]
    assert hold["completed"] and hold["t_end"] - hold["t_start"] == pytest.approx(10_000, abs=1e-3)
    assert list(seg["index"]) == [0, 1, 2]


def test_a_dollar_in_the_plan_name_is_text_in_the_report(tmp_path):
    path = protocol(tmp_path, BASE.replace("name: t", "name: \"cost $5 and $x^2$ {\\\\bf}\""))
    out = tmp_path / "r.h5"
    invoke("run", path, "--output", str(out), allowed=(0,))
    res = invoke("report", str(out), "--out", str(tmp_path / "rep"), allowed=(0,))
    assert "index.html" in res.output


@pytest.mark.skipif(sys.platform == "win32", reason="FIFOs")
def test_a_fifo_is_refused_at_once_not_read(tmp_path):
    fifo = tmp_path / "run.h5"
    os.mkfifo(fifo)
    for args in (["info", str(fifo)], ["validate", str(fifo)], ["import", str(fifo), "--out", str(tmp_path / "x.h5")],
                 ["predict", str(fifo), str(fifo)], ["validate", str(PROTOCOL), "--bench", str(fifo)]):
        res = invoke(*args, allowed=(2,))
        assert "FIFO" in res.output, res.output


def test_csv_integers_out_of_range_are_refused_not_wrapped(tmp_path):
    c = tmp_path / "c.csv"
    c.write_text("t [s],position_raw,counter\n0,100,0\n0.1,40000,1\n0.2,5,4294967296\n")
    res = invoke("import", str(c), "--out", str(tmp_path / "x.h5"), allowed=(2,))
    assert f"{c}:3: column 'position_raw'" in res.output and "-32768..32767" in res.output
    assert f"{c}:4: column 'counter'" in res.output and not (tmp_path / "x.h5").exists()


def test_a_bench_with_an_invalid_plant_fails_validate(tmp_path):
    sim = ROOT / "configs/bench/sim.yaml"
    b = tmp_path / "b.yaml"
    b.write_text(sim.read_text().replace("play_turns:", "play_turns: -3 #", 1))
    res = invoke("validate", str(PROTOCOL), "--bench", str(b), allowed=(2,))
    line = next(i for i, t in enumerate(b.read_text().splitlines(), 1) if "play_turns: -3" in t)
    assert "play_turns" in res.output and f"{b}:{line}:" in res.output, res.output
    b.write_text(sim.read_text().replace("ohm_per_mm:", "ohm_per_mm: -1e300 #", 1))  # overflows when run
    res = invoke("validate", str(PROTOCOL), "--bench", str(b), allowed=(2,))
    assert "no finite reading" in res.output, res.output
    b.write_text(sim.read_text().replace("operators:", "operators: 1e300 #", 1))  # took for ever to build
    res = invoke("effects", "--bench", str(b), allowed=(2,))
    assert "'operators' must be <= 1000" in res.output, res.output


@pytest.mark.parametrize("change, message", [
    (lambda t: t[::-1].copy(), "not increasing"),
    (lambda t: np.where(np.arange(len(t)) == 5, np.nan, t), "NaN"),
    (lambda t: np.where(np.arange(len(t)) == 5, 1e308, t), "at most"),
])
def test_run_files_with_impossible_time_are_refused_by_every_reader(tmp_path, good, change, message):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(good["run"].read_bytes())
    with h5py.File(bad, "a") as f:
        t = change(f["samples/t"][()])
        del f["samples/t"]
        f["samples"].create_dataset("t", data=t).attrs["units"] = "s"
    for args in (["info", str(bad)], ["diagnose", str(bad), "--out", str(tmp_path / "d")],
                 ["report", str(bad), "--out", str(tmp_path / "r")], ["export", str(bad), "--csv"],
                 ["fit", "polynomial", str(bad), "--out", str(tmp_path / "m.json")]):
        res = invoke(*args, allowed=(2,))
        assert message in res.output and "/samples/t" in res.output, res.output


@pytest.mark.skipif(sys.platform == "win32", reason="FIFOs")
def test_links_in_a_run_file_are_refused_without_following_them(tmp_path, good):
    fifo = tmp_path / "elsewhere.h5"
    os.mkfifo(fifo)
    bad = tmp_path / "bad.h5"
    bad.write_bytes(good["run"].read_bytes())
    with h5py.File(bad, "a") as f:
        del f["samples/length"]
        f["samples/length"] = h5py.ExternalLink(str(fifo), "/samples/length")
    res = invoke("info", str(bad), allowed=(2,))
    assert "/samples/length is an external link" in res.output


@pytest.mark.parametrize("port", ["spy://x?file=/tmp/anywhere", "socket://localhost:9", "rfc2217://h:1", "loop://"])
def test_only_device_paths_and_sim_urls_are_ports_unless_allowed(tmp_path, port):
    res = invoke("run", str(PROTOCOL), "--port", port, "--output", str(tmp_path / "r.h5"), allowed=(2,))
    assert "--allow-url" in res.output and not (tmp_path / "r.h5").exists()
    b = tmp_path / "b.yaml"
    b.write_text(BENCH.read_text().replace("backend: sim", f"backend: serial\nport: '{port}'"))
    res = invoke("validate", str(PROTOCOL), "--bench", str(b), allowed=(2,))
    assert "--allow-url" in res.output and f"{b}:" in res.output
    invoke("validate", str(PROTOCOL), "--bench", str(b), "--allow-url", allowed=(0,))


def test_an_allowed_url_is_then_used(tmp_path):
    """loop:// echoes our own frames: allowed with --allow-url, it is no device (exit 1)."""
    quick = tmp_path / "quick.yaml"
    quick.write_text(BENCH.read_text().replace("boot_timeout_s: 3.0", "boot_timeout_s: 0.1")
                     .replace("ack_timeout_s: 0.25", "ack_timeout_s: 0.05"))
    res = invoke("run", str(PROTOCOL), "--bench", str(quick), "--port", "loop://", "--allow-url",
                 "--output", str(tmp_path / "r.h5"), allowed=(1,))
    assert "no answer from a tsa-bench device" in res.output
