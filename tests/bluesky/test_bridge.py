"""The documents bridge both ways: Bluesky runs into run files that `info` and `fit` read,
and run files out as Bluesky documents (`tsa-bench export --documents`)."""

from __future__ import annotations

import json
import sys
import threading
import time

import bluesky.plan_stubs as bps
import bluesky.plans as bp
import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from event_model import schema_validators, DocumentNames

from tests.bluesky.helpers import connect, make_re
from tsa_bench.bluesky import ProtocolFlyer, RunFileWriter, run_documents, run_protocol
from tsa_bench.cli import main
from tsa_bench.store import read_run


@pytest.fixture
def session(tmp_path):
    re, rec = make_re()
    rig = connect("sim://?seed=11")
    writer = RunFileWriter(tmp_path / "runs", rig=rig)
    re.subscribe(writer)
    yield re, rec, rig, writer
    rig.close()


def _cli(*args: str):
    return CliRunner().invoke(main, list(args))


def test_a_scan_becomes_a_run_file_that_info_and_fit_read(session, tmp_path):
    re, rec, rig, writer = session
    re(bps.mv(rig.load, 200))
    re(bp.scan([rig.length, rig.resistance], rig.twist, 0, 40, 9))
    (path,) = writer.paths
    run = read_run(path)
    events = rec.events()
    assert run.attrs["exit_status"] == "success" and run.attrs["backend"] == "sim"
    assert run.samples["turns"].tolist() == [e["data"]["rig-twist"] for e in events]
    assert run.samples["length"].tolist() == [e["data"]["rig-length"] for e in events]
    assert run.samples["resistance"].tolist() == [e["data"]["rig-resistance"] for e in events]
    assert run.samples["load"] == pytest.approx(200 * 9.80665e-3)      # g -> N
    assert np.all(np.diff(run.samples["t"]) > 0) and run.samples["t"][0] == 0.0
    assert run.bench_text == rig.bench.source_text
    info = _cli("info", str(path))
    assert info.exit_code == 0, info.output
    assert "length" in info.output and "success" in info.output
    fit = _cli("fit", "polynomial", str(path), "--out", str(tmp_path / "poly.json"))
    assert fit.exit_code == 0, fit.output
    model = json.loads((tmp_path / "poly.json").read_text())
    assert model["input"]["column"] == "turns" and model["output"]["column"] == "length"


def test_a_count_of_length_alone_stores_the_rest_of_its_acquisition(session):
    re, rec, rig, writer = session
    re(bp.count([rig.length], 5))
    run = read_run(writer.paths[0])
    assert np.isfinite(run.samples["resistance"]).all()        # looked up from the rig's acquisitions
    assert run.samples["t"].tolist() == pytest.approx([0.0, 0.5, 1.0, 1.5, 2.0])   # device time, 0.5 s windows
    assert (run.samples["segment"] == -1).all() and (run.samples["motor_moving"] == 0).all()


def test_a_protocol_run_through_the_bridge_matches_its_own_documents(session):
    re, rec, rig, writer = session
    flyer = ProtocolFlyer(rig, "twist-sweep-3ply.yaml", name="sweep")
    re(run_protocol(flyer))
    run = read_run(writer.paths[0])
    pages = [p for p in rec.of("event_page") if "sweep-length" in p["data"]]
    length = [v for p in pages for v in p["data"]["sweep-length"]]
    assert len(run) == len(length) and np.array_equal(run.samples["length"], length, equal_nan=True)
    assert run.protocol_text == flyer.plan.source_text
    assert len(run.segments) == len(flyer.plan.segments)
    assert run.attrs["plan_name"] == flyer.plan.name


def test_an_aborted_run_file_says_so(session):
    re, rec, rig, writer = session

    def abort_after_the_first_point():
        deadline = time.monotonic() + 60
        while not rec.events() and time.monotonic() < deadline:
            time.sleep(0.005)
        re.abort("test: abort after the first point")

    threading.Thread(target=abort_after_the_first_point, daemon=True).start()
    with pytest.raises(Exception):
        re(bp.count([rig.length], 1000))
    run = read_run(writer.paths[0])
    assert run.attrs["exit_status"] == "aborted" and 1 <= len(run) < 1000
    assert "ended 'abort'" in run.attrs["reason"]


def test_an_existing_file_is_never_overwritten(tmp_path):
    re, rec = make_re()
    rig = connect("sim://?seed=1")
    try:
        target = tmp_path / "kept.h5"
        target.write_bytes(b"recorded data")
        re.subscribe(RunFileWriter(target, rig=rig))
        with pytest.raises(FileExistsError, match="nothing was overwritten"):
            re(bp.count([rig.length], 1))
        assert target.read_bytes() == b"recorded data"
    finally:
        rig.close()


def test_export_documents_are_valid_and_write_back_to_the_same_samples(tmp_path):
    src = tmp_path / "src.h5"
    ran = _cli("run", "twist-sweep-3ply.yaml", "--seed", "2", "--output", str(src))
    assert ran.exit_code == 0, ran.output
    out = tmp_path / "docs.jsonl"
    exported = _cli("export", str(src), "--documents", "--output", str(out))
    assert exported.exit_code == 0, exported.output
    docs = [json.loads(line) for line in out.read_text().splitlines()]
    assert docs[0][0] == "start" and docs[-1][0] == "stop"
    for name, doc in docs:
        schema_validators[DocumentNames(name)].validate(doc)
    # back through the bridge (JSON lines carry NaN as null)
    writer = RunFileWriter(tmp_path / "back.h5")
    for name, doc in docs:
        writer(name, doc)
    original, back = read_run(src), read_run(tmp_path / "back.h5")
    for col in ("t", "turns", "length", "resistance", "heater_voltage", "load", "segment", "motor_moving"):
        assert np.array_equal(original.samples[col], back.samples[col], equal_nan=True), col
    assert len(back.segments) == len(original.segments)
    assert back.protocol_text == original.protocol_text and back.bench_text == original.bench_text
    assert back.attrs["exit_status"] == "success"
    assert _cli("export", str(src), "--documents", "--output", str(out)).exit_code == 2   # never overwritten


def test_export_documents_without_the_extra_says_how_to_install_it(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "event_model", None)
    monkeypatch.delitem(sys.modules, "tsa_bench.bluesky.export", raising=False)
    res = _cli("export", str(tmp_path / "x.h5"), "--documents")
    assert res.exit_code == 2 and 'pip install "tsa-bench[bluesky]"' in res.output
