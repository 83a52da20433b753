"""`tsa-bench lab`: several rigs at once, each run the file it would be alone; one rig's
lost link stops no other; one Ctrl-C stops them all safely; a bad lab file moves nothing."""

from __future__ import annotations

import importlib.util
import os
import signal
import subprocess
import sys
from pathlib import Path

import h5py

from tests.catalogue.helpers import ENV, ROOT, cli, live_samples, short_protocol, wait_for
from tests.faults.ptybench import quick_bench, relayed_sim
from tsa_bench import catalogue
from tsa_bench.lab.labfile import read_lab

LOADS = {"A": 200, "B": 350, "C": 450, "D": 550}


def _identity():
    spec = importlib.util.spec_from_file_location("run_identity", ROOT / "scripts" / "bench" / "run_identity.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _lab_file(tmp_path: Path, rigs: dict[str, str], speed: float | None = None) -> Path:
    short_protocol(tmp_path)
    lines = ["name: test-lab", "defaults: {protocol: short-life.yaml, bench: sim"
             + (f", speed: {speed}" if speed else "") + "}", "rigs:"]
    lines += [f"  - {{name: {name}, {extra}}}" for name, extra in rigs.items()]
    path = tmp_path / "lab.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def _sim_rig(name: str, seed: int) -> str:
    return f"seed: {seed}, variables: {{load_g: {LOADS[name]}}}, meta: {{sample: S{seed}}}"


def _start_lab(lab: Path, out: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", "lab", str(lab), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True,
                            env=ENV, cwd=ROOT, start_new_session=True)


def _file_of(out: Path, rig: str) -> Path | None:
    found = sorted(out.glob(f"*_{rig}_short-life.h5"))
    return found[0] if found else None


def test_the_shipped_lab_has_four_simulated_rigs_with_four_loads_and_seeds():
    lab = read_lab(ROOT / "configs" / "labs" / "four-sim-rigs.yaml")
    assert [r.backend for r in lab.rigs] == ["sim"] * 4 and {r.plan_name for r in lab.rigs} == {"lifetime"}
    assert len({r.seed for r in lab.rigs}) == 4 and len({r.load_g for r in lab.rigs}) == 4


def test_four_rigs_at_once_record_what_each_records_alone(tmp_path):
    lab = _lab_file(tmp_path, {name: _sim_rig(name, i + 1) for i, name in enumerate(LOADS)})
    out = tmp_path / "lab-runs"
    res = cli("lab", str(lab), "--out", str(out))
    assert res.returncode == 0, res.stdout + res.stderr
    assert res.stdout.strip().endswith("4 of 4 rigs succeeded")
    identity = _identity()
    for i, name in enumerate(LOADS):
        alone = tmp_path / "alone" / f"{name}.h5"
        one = cli("run", str(tmp_path / "short-life.yaml"), "--seed", str(i + 1), "--set",
                  f"load_g={LOADS[name]}", "--output", str(alone), "--catalogue", "none")
        assert one.returncode == 0, one.stderr
        assert identity.differences(_file_of(out, name), alone, ROOT) == [], name
    with catalogue.open(out) as cat:
        rows = sorted(cat.search(), key=lambda r: r.rig)
    assert [(r.rig, r.status, r.load_g, r.sample, r.meta["lab"]) for r in rows] == [
        (name, "success", float(LOADS[name]), f"S{i + 1}", "test-lab") for i, name in enumerate(LOADS)]
    assert all(r.file_state() == "ok" and r.samples > 500 for r in rows)


def test_a_rig_that_loses_its_link_leaves_the_other_three_complete(tmp_path):
    bench = quick_bench(tmp_path)
    with relayed_sim(bench, speed=5.0, seed=2) as relay:
        rigs = {name: _sim_rig(name, i + 1) for i, name in enumerate(LOADS)}
        rigs["B"] = f"port: {relay.path}, bench: {bench}, meta: {{sample: S2}}"
        out = tmp_path / "lab-runs"
        lab = _start_lab(_lab_file(tmp_path, rigs), out)
        try:
            wait_for(lambda: _file_of(out, "B") and live_samples(_file_of(out, "B")) > 20, "rig B's first samples")
            relay.link.faults.cut_at_s = relay.link.now_s()     # B's cable is pulled
            stdout, stderr = lab.communicate(timeout=300)
        finally:
            if lab.poll() is None:
                lab.kill()
    assert lab.returncode == 1, stdout + stderr
    status = {}
    for name in LOADS:
        with h5py.File(_file_of(out, name), "r") as f:
            status[name] = (f.attrs["exit_status"], bool(f["segments"]["completed"].all()))
    assert status == {"A": ("success", True), "B": ("failed", False), "C": ("success", True), "D": ("success", True)}
    assert "3 of 4 rigs succeeded" in stdout
    assert any(line.startswith("B ") and "failed" in line for line in stdout.splitlines())


def test_one_ctrl_c_stops_every_rig_and_closes_every_file_aborted(tmp_path):
    lab_file = _lab_file(tmp_path, {name: _sim_rig(name, i + 1) for i, name in enumerate(LOADS)}, speed=5)
    out = tmp_path / "lab-runs"
    lab = _start_lab(lab_file, out)
    try:
        wait_for(lambda: all(_file_of(out, n) and live_samples(_file_of(out, n)) > 10 for n in LOADS),
                 "samples from every rig")
        os.killpg(lab.pid, signal.SIGINT)       # the terminal's Ctrl-C reaches the lab's process group
        stdout, stderr = lab.communicate(timeout=120)
    finally:
        if lab.poll() is None:
            lab.kill()
    assert lab.returncode == 130, stdout + stderr
    assert "Ctrl-C: stopping every rig" in stdout
    for name in LOADS:
        with h5py.File(_file_of(out, name), "r") as f:
            assert f.attrs["exit_status"] == "aborted", name
            assert b"stop_sent" in set(f["events"]["kind"][()]), name
            assert "Ctrl-C" in f.attrs["reason"]
    with catalogue.open(out) as cat:
        assert sorted(r.status for r in cat.search()) == ["aborted"] * 4


def test_every_problem_of_a_lab_file_is_said_at_once_and_nothing_moves(tmp_path):
    short_protocol(tmp_path)
    lab = tmp_path / "lab.yaml"
    lab.write_text(
        "name: bad lab\n"
        "rigs:\n"
        "  - {name: A, protocol: short-life.yaml, bench: sim, bogus: 1}\n"
        "  - {name: B, protocol: short-life.yaml, bench: sim}\n"
        "  - {name: B, protocol: short-life.yaml, bench: sim}\n"
        "  - {name: C, protocol: short-life.yaml}\n"
        "  - {name: D, protocol: short-life.yaml, bench: sim, variables: {weight: 3}}\n"
        "  - {name: E, protocol: short-life.yaml, bench: arduino-mega, port: /dev/ttyNOPE9, seed: 3}\n"
        "  - {name: F, protocol: short-life.yaml, bench: nothere.yaml}\n")
    out = tmp_path / "lab-runs"
    res = cli("lab", str(lab), "--out", str(out))
    assert res.returncode == 2 and "Traceback" not in res.stderr
    said = res.stderr
    for line, words in ((1, "lab name 'bad lab'"), (3, "unknown key 'bogus'"), (5, "rig B: the name is already used"),
                        (6, "rig C: no bench"), (7, "rig D: the protocol is not valid"),
                        (8, "no serial device /dev/ttyNOPE9"), (8, "seed applies only to a simulated rig"),
                        (9, "rig F: the bench file is not usable")):
        assert any(f"{lab}:{line}:" in ln and words in ln for ln in said.splitlines()), (line, words, said)
    assert f"{tmp_path / 'short-life.yaml'}:2:" in said and "weight, which this protocol does not declare" in said
    assert not out.exists()
