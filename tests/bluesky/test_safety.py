"""Safety carries over into Bluesky: a RunEngine abort, stop or pause in the middle of a
move sends STOP; the motor halts short of its target and the heater goes off, as the
device's own samples say afterwards (simulated bench and native firmware behind a pty)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import bluesky.plan_stubs as bps
import bluesky.preprocessors as bpp
import pytest
from bluesky.utils import RunEngineInterrupted

from tests.bluesky.helpers import connect, make_re, native_relay, quick_bench, record_commands
from tsa_bench.protocol import msg

TARGET_TURNS = 60.0   # 60 s of motion at the default 1 turn/s: long enough to be interrupted mid-way
HEATER_V = 4.0


def _heat_then_twist(rig):
    @bpp.run_decorator(md={"plan_name": "heat_then_twist"})
    def plan():
        yield from bps.checkpoint()
        yield from bps.mv(rig.heater, HEATER_V)
        yield from bps.mv(rig.twist, TARGET_TURNS)
    return plan()


def _interrupt_once(condition: Callable[[], bool], interrupt: Callable[[], object]) -> threading.Thread:
    """Call ``interrupt`` from another thread as soon as ``condition`` holds (60 s at most)."""
    def watch() -> None:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if condition():
                interrupt()
                return
            time.sleep(0.005)

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


def _run_interrupted(re, rig, how: str, sent: list[str]) -> None:
    """Run the plan; interrupt it ``how`` once the move to TARGET_TURNS has been sent."""
    interrupt = {"abort": lambda: re.abort("test: abort mid-move"), "stop": re.stop,
                 "pause": lambda: re.request_pause(defer=False)}[how]
    watcher = _interrupt_once(lambda: "MoveTo" in sent, interrupt)
    with pytest.raises(RunEngineInterrupted):    # RE() raises it for an abort, a stop and a pause alike
        re(_heat_then_twist(rig))
    watcher.join(60)
    if how == "pause":
        assert re.state == "paused"


def _at_rest(rig):
    """Two acquisitions from the device: (the later one, whether the motor stood still between them)."""
    first = rig.session.submit(rig.session.acquire, 0.3).result(timeout=120)
    second = rig.session.submit(rig.session.acquire, 0.3).result(timeout=120)
    return second, first.step_position == second.step_position


@pytest.mark.parametrize("how", ["abort", "stop", "pause"])
def test_an_interrupted_plan_stops_the_motor_and_switches_the_heater_off(how, monkeypatch):
    re, rec = make_re()
    rig = connect("sim://?seed=4&speed=5")     # 60 turns take 12 s of wall time at most
    try:
        sent = record_commands(rig, monkeypatch)
        _run_interrupted(re, rig, how, sent)
        assert "Stop" in sent[sent.index("MoveTo"):]
        after, still = _at_rest(rig)
        assert after.heater_V == 0.0                        # the device's samples: heater off
        assert 0.0 <= after.turns < TARGET_TURNS and still  # halted short of the target, not moving
        if how == "pause":
            re.abort("test: done")
        expected = {"abort": "abort", "stop": "success", "pause": "abort"}[how]
        assert rec.of("stop")[-1]["exit_status"] == expected
    finally:
        rig.close()


def test_an_abort_on_the_native_firmware_sends_stop_over_the_wire(tmp_path):
    """The same abort against the firmware core behind a pty: the relay sees the STOP go
    down the line, and the firmware's own samples show the heater off and the motor still."""
    with native_relay("--speed", "5") as relay:
        re, rec = make_re()
        rig = connect(relay.path, quick_bench(tmp_path, "arduino-mega.yaml"))
        try:
            frames = relay.link.host_frames
            watcher = _interrupt_once(lambda: frames.count(msg.MoveTo) > 0, lambda: re.abort("test: abort"))
            with pytest.raises(RunEngineInterrupted):
                re(_heat_then_twist(rig))
            watcher.join(60)
            assert frames.count(msg.Stop) >= 1
            after, still = _at_rest(rig)
            samples = relay.link.device_frames.samples()      # by counter, sample blocks expanded
            assert samples and samples[max(samples)].heater_mV == 0 and after.heater_V == 0.0
            assert 0.0 <= after.turns < TARGET_TURNS and still
            assert rec.of("stop")[-1]["exit_status"] == "abort"
        finally:
            rig.close()
