"""A YAML protocol as one step of a Bluesky plan: the runner on the rig, samples as events."""

from __future__ import annotations

import threading
import time

import bluesky.plan_stubs as bps
import bluesky.plans as bp
import bluesky.preprocessors as bpp
import pytest
from bluesky.utils import FailedStatus, RunEngineInterrupted

from tests.bluesky.helpers import connect, make_re
from tsa_bench.bluesky import ProtocolFlyer, run_protocol
from tsa_bench.bluesky.flyer import ProtocolRejected
from tsa_bench.rig.link import RigLink

LONG = """\
name: long-hold
load_g: 200
sampling_period_s: 0.1
defaults: {rate_turns_per_s: 1, accel_turns_per_s2: 10}
steps:
  - move_to: {turns: 10}
  - hold: {duration_s: 600}
  - move_to: {turns: 0}
"""


def test_a_thesis_protocol_runs_as_one_plan_step_and_streams_its_samples(session):
    re, rec, rig = session
    flyer = ProtocolFlyer(rig, "twist-sweep-4ply.yaml", name="sweep")
    re(run_protocol(flyer, poll_s=0.05))
    descriptors = {d["name"]: d for d in rec.of("descriptor")}
    assert set(descriptors) == {"sweep", "sweep_segments", "sweep_events"}
    keys = descriptors["sweep"]["data_keys"]
    assert keys["sweep-length"]["units"] == "mm" and keys["sweep-load"]["units"] == "N"
    pages = [p for p in rec.of("event_page") if p["descriptor"] == descriptors["sweep"]["uid"]]
    turns = [t for p in pages for t in p["data"]["sweep-turns"]]
    segments = [s for p in rec.of("event_page") if p["descriptor"] == descriptors["sweep_segments"]["uid"]
                for s in p["data"]["sweep-segment_kind"]]
    assert max(turns) == 81.0 and turns[-1] == 0.0          # 0 -> 81 -> 0 turns, three times
    assert len(segments) == len(flyer.plan.segments)        # every protocol step, executed
    assert rec.of("stop")[0]["exit_status"] == "success"
    assert rec.of("stop")[0]["num_events"]["sweep"] == len(turns)
    config = descriptors["sweep"]["configuration"]["sweep"]["data"]
    assert config["sweep-protocol"].startswith("# Twisting-induced actuation")
    # the rig's own readings go on after the protocol (sampling restored, load the last declared)
    re(bp.count([rig.length], 1))
    assert rig.session.load_g == pytest.approx(250.0)


def test_fly_collects_once_at_the_end(session, tmp_path):
    re, rec, rig = session
    path = tmp_path / "short.yaml"
    path.write_text(LONG.replace("600", "20"))
    re(bp.fly([ProtocolFlyer(rig, path, name="p")]))
    assert rec.of("stop")[0]["exit_status"] == "success"
    samples = [p for p in rec.of("event_page") if "p-length" in p["data"]]
    assert len(samples) == 1 and len(samples[0]["seq_num"]) > 200    # 20 s hold + moves at 0.1 s


def test_a_bad_protocol_is_refused_with_its_line_before_anything_moves(session, tmp_path):
    _, _, rig = session
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nsampling_period_s: 0.1\nsteps:\n  - move_to: {turns: 500}\n")
    with pytest.raises(ProtocolRejected, match=r"bad.yaml:4"):
        ProtocolFlyer(rig, bad)


def test_the_rig_refuses_moves_and_readings_while_a_protocol_runs(session, tmp_path):
    re, rec, rig = session
    path = tmp_path / "long.yaml"
    path.write_text(LONG)
    flyer = ProtocolFlyer(rig, path, name="long")

    @bpp.run_decorator()
    def plan():
        yield from bps.kickoff(flyer, wait=True)
        yield from bps.mv(rig.twist, 5)

    with pytest.raises(FailedStatus) as err:
        re(plan())
    assert "a protocol is running on the rig" in str(err.value.__cause__)
    # the RunEngine's cleanup stopped the protocol (the twist it touched): it ended aborted
    assert flyer._job.result(timeout=60).exit_status == "aborted"


@pytest.mark.parametrize("how", ["abort", "pause"])
def test_an_abort_or_a_pause_mid_protocol_stops_it(tmp_path, how):
    """RE.abort() or RE.request_pause() while run_protocol waits: the protocol gets STOP and
    ends aborted, early (a protocol cannot wait half-way for a resume)."""
    re, rec = make_re()
    rig = connect("sim://?seed=5&speed=50")      # the 600 s hold takes 12 s of wall time
    try:
        path = tmp_path / "long.yaml"
        path.write_text(LONG)
        flyer = ProtocolFlyer(rig, path, name="long")

        def abort_when_holding():
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline:
                col = flyer._collector
                if col is not None and any(len(b) and b.columns["turns"][-1] == 10 for b in list(col.blocks)):
                    if how == "abort":
                        re.abort("test: abort mid-protocol")
                    else:
                        re.request_pause(defer=False)
                    return
                time.sleep(0.01)

        threading.Thread(target=abort_when_holding, daemon=True).start()
        if how == "abort":
            with pytest.raises(Exception):
                re(run_protocol(flyer, poll_s=5.0))   # polls rarely: the abort lands while it waits
        else:
            with pytest.raises(RunEngineInterrupted):
                re(run_protocol(flyer, poll_s=5.0))
            assert re.state == "paused"
        stop = flyer._job.result(timeout=60)
        assert stop.exit_status == "aborted" and stop.t_end < 300
        if how == "pause":
            re.abort("test: done")
        assert rec.of("stop")[0]["exit_status"] == "abort"
    finally:
        rig.close()


def test_a_prompt_on_a_real_rig_stops_the_protocol_and_says_what_it_asked(session, tmp_path, monkeypatch):
    re, rec, rig = session
    rig.declare_twist(0)
    monkeypatch.setattr(RigLink, "simulated", property(lambda self: False))
    path = tmp_path / "prompt.yaml"
    path.write_text("name: p\nsampling_period_s: 0.1\ndefaults: {rate_turns_per_s: 1, accel_turns_per_s2: 10}\nsteps:\n  - move_to: {turns: 2}\n"
                    "  - prompt: {text: 'Hang [200 g] now', load_g: 200}\n  - hold: {duration_s: 1}\n")
    with pytest.raises(FailedStatus) as err:
        re(run_protocol(ProtocolFlyer(rig, path, name="p")))
    text = str(err.value.__cause__)
    assert "ended failed" in text and "'Hang [200 g] now'" in text and "tsa-bench run" in text
    assert "a Bluesky plan asks nobody at a terminal" in text   # OperatorRefusal said why
    assert rec.of("stop")[0]["exit_status"] == "fail"
