"""The rig device on devices in another process, opened by path like a Mega's serial
port: `tsa-bench sim-serve` and the firmware core built natively, behind a pty. The same
device client as every other command (the relay in front of the firmware records what
went down the line)."""

from __future__ import annotations

import math
import subprocess
import sys

import bluesky.plans as bp
import pytest
from bluesky.utils import FailedStatus

from tests.bluesky.helpers import ROOT, build_native, connect, make_re, native_relay, quick_bench
from tests.rig.native_pty import NativeFirmwarePty
from tsa_bench.bluesky import PositionUnknown, ProtocolFlyer, run_protocol
from tsa_bench.protocol import msg


SHORT = """\
name: short
sampling_period_s: 0.1
defaults: {rate_turns_per_s: 2, accel_turns_per_s2: 20}
steps:
  - move_to: {turns: 4}
  - hold: {duration_s: 2}
  - move_to: {turns: 0}
"""


def test_count_scan_heater_list_scan_and_a_protocol_on_the_native_firmware(tmp_path):
    with native_relay("--virtual") as relay:
        re, rec = make_re()
        rig = connect(relay.path, quick_bench(tmp_path, "arduino-mega.yaml"))
        try:
            re(bp.count([rig.length, rig.resistance], 3))
            re(bp.scan([rig.length, rig.resistance], rig.twist, 0, 8, 3))
            sent = list(relay.link.host_frames.messages)     # down the line for the count and the scan
            re(bp.list_scan([rig.resistance], rig.heater, [0.0, 3.0]))
            heated = rec.events()[6:]
            path = tmp_path / "short.yaml"
            path.write_text(SHORT)
            re(run_protocol(ProtocolFlyer(rig, path, name="short"), poll_s=0.1))
        finally:
            rig.close()
        assert [e["data"]["rig-heater"] for e in heated] == pytest.approx([0.0, 3.0], abs=12 / 255)
        assert math.isfinite(heated[0]["data"]["rig-resistance"]) and math.isnan(heated[1]["data"]["rig-resistance"])
        samples = [t for p in rec.of("event_page") if "short-turns" in p["data"] for t in p["data"]["short-turns"]]
        assert max(samples) <= 8.0 and samples.count(4.0) >= 15 and samples[-1] == 0.0   # 8 (the scan) -> 4, 2 s -> 0
        assert rec.of("stop")[-1]["exit_status"] == "success"
        events = rec.events()[:6]
        assert all(150 < e["data"]["rig-length"] < 375 for e in events)           # the sensor's span (mm)
        assert all(math.isfinite(e["data"]["rig-resistance"]) for e in events)    # heater off: measured
        assert [e["data"]["rig-twist"] for e in events[3:]] == pytest.approx([0, 4, 8], abs=1e-3)
        # what went down the line (a retransmission repeats a frame: count segments): the device
        # client's own commands, a move per scan point, an acquisition (DWELL) per event
        assert len({m.segment for m in sent if isinstance(m, msg.MoveTo)}) == 3
        assert len({m.segment for m in sent if isinstance(m, msg.Dwell)}) == 6


def test_count_on_sim_serve(tmp_path):
    bench = quick_bench(tmp_path, "sim.yaml")
    server = subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", "sim-serve", "--bench", str(bench)],
                              cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        path = server.stdout.readline().strip()
        assert path.startswith("/dev/"), server.stderr.read()
        re, rec = make_re()
        rig = connect(path, bench)
        try:
            re(bp.count([rig.length, rig.resistance], 3))
            assert rig.session.link.simulated
        finally:
            rig.close()
    finally:
        server.terminate()
        server.wait(10)
    events = rec.events()
    assert len(events) == 3 and all(150 < e["data"]["rig-length"] < 375 for e in events)
    assert rec.of("descriptor")[0]["data_keys"]["rig-resistance"]["units"] == "ohm"


def test_firmware_passing_for_a_mega_that_lost_its_zero_refuses_to_stage(tmp_path):
    """No SIMULATED flag, position unknown at power-up: staging fails with what to do,
    nothing moves, and declare_twist() answers the question."""
    with NativeFirmwarePty(build_native(), "--virtual", as_hardware=True) as fw:
        re, rec = make_re()
        rig = connect(fw.path, quick_bench(tmp_path, "arduino-mega.yaml"))
        try:
            assert not rig.session.link.simulated
            with pytest.raises(FailedStatus) as refused:
                re(bp.scan([rig.length], rig.twist, 0, 4, 2))
            assert isinstance(refused.value.__cause__, PositionUnknown)
            assert "rig.declare_twist(0)" in str(refused.value.__cause__)
            assert rec.events() == [] and rig.session.position_steps == 0
            rig.declare_twist(0)
            re(bp.scan([rig.length], rig.twist, 0, 4, 2))
            assert [e["data"]["rig-twist"] for e in rec.events()] == pytest.approx([0, 4], abs=1e-3)
        finally:
            rig.close()
