"""The rig as an ophyd-async device under the real RunEngine, on the simulated bench (sim://)."""

from __future__ import annotations

import math

import bluesky.plan_stubs as bps
import bluesky.plans as bp
import pytest
from bluesky.utils import FailedStatus

from tests.bluesky.helpers import connect, record_commands
from tsa_bench.bluesky import PositionUnknown, RigRefused
from tsa_bench.protocol import msg
from tsa_bench.rig.link import RigLink


def test_count_takes_ten_acquisitions_with_units_in_the_descriptor(session):
    re, rec, rig = session
    re(bp.count([rig.length], 10))
    events = rec.events()
    assert len(events) == 10
    values = [e["data"]["rig-length"] for e in events]
    assert all(150 < v < 375 for v in values)        # within the position sensor's span (mm)
    stamps = [e["timestamps"]["rig-length"] for e in events]
    assert stamps == sorted(set(stamps))              # ten acquisitions, not one read ten times
    key = rec.of("descriptor")[0]["data_keys"]["rig-length"]
    assert key["units"] == "mm" and key["precision"] == 4 and key["source"].endswith("#length")
    assert rec.of("stop")[0]["exit_status"] == "success"


def test_scan_moves_the_twist_and_reads_length_and_resistance_from_one_acquisition(session):
    re, rec, rig = session
    re(bp.scan([rig.length, rig.resistance], rig.twist, 0, 40, 9))
    events = rec.events()
    assert [e["data"]["rig-twist"] for e in events] == pytest.approx([0, 5, 10, 15, 20, 25, 30, 35, 40], abs=1e-3)
    for e in events:
        assert e["timestamps"]["rig-length"] == e["timestamps"]["rig-resistance"]  # the same samples
    lengths = [e["data"]["rig-length"] for e in events]
    assert lengths[-1] < lengths[0] - 20              # twisting shortens the TSA by tens of mm
    assert all(math.isfinite(e["data"]["rig-resistance"]) for e in events)
    keys = rec.of("descriptor")[0]["data_keys"]
    assert keys["rig-twist"]["units"] == "turn"
    assert keys["rig-twist"]["limits"]["control"] == {"low": -10.0, "high": 100.0}   # configs/bench/sim.yaml
    assert keys["rig-resistance"]["units"] == "ohm"
    config = rec.of("descriptor")[0]["configuration"]["rig-twist"]["data_keys"]
    assert config["rig-twist-velocity"]["limits"]["control"]["high"] == 5.0


def test_list_scan_over_heater_voltages_reads_resistance_as_nan_while_heating(session):
    re, rec, rig = session
    re(bp.list_scan([rig.length, rig.resistance], rig.heater, [0.0, 2.0, 4.0]))
    events = rec.events()
    # the readback is the voltage the heater's PWM applies (its steps are 12 V / 255 wide)
    assert [e["data"]["rig-heater"] for e in events] == pytest.approx([0.0, 2.0, 4.0], abs=12 / 255)
    assert math.isfinite(events[0]["data"]["rig-resistance"])
    assert math.isnan(events[1]["data"]["rig-resistance"]) and math.isnan(events[2]["data"]["rig-resistance"])
    # the plan ended: the heater is off on the device (its samples say so)
    re(bp.count([rig.heater], 1))
    assert rec.events()[-1]["data"]["rig-heater"] == 0.0


def test_moves_beyond_the_bench_limits_are_refused_before_anything_is_sent(session, monkeypatch):
    re, _, rig = session
    sent = record_commands(rig, monkeypatch)
    with pytest.raises(FailedStatus) as twist:
        re(bps.mv(rig.twist, 101))
    assert "outside the limits -10..100 turns" in str(twist.value.__cause__ or twist.value)
    with pytest.raises(FailedStatus) as heat:
        re(bps.mv(rig.heater, 12.5))
    assert "above the bench's limit of 12 V" in str(heat.value.__cause__ or heat.value)
    assert "MoveTo" not in sent and "SetHeater" not in sent


def test_the_device_refuses_what_the_host_check_would_have_caught(session, monkeypatch):
    """With the host-side check bypassed, the device's own twist limit still holds."""
    re, _, rig = session
    monkeypatch.setattr(rig.session, "check_twist", lambda *a: None)
    with pytest.raises(FailedStatus) as err:
        re(bps.mv(rig.twist, 101))
    assert "limit_exceeded" in str(err.value.__cause__ or err.value)
    assert rig.session.position_steps == 0


def test_a_real_rig_that_lost_its_twist_zero_refuses_to_stage_until_it_is_declared(session, monkeypatch):
    """No question on a terminal: staging fails with what to do; declare_twist answers it."""
    re, rec, rig = session
    monkeypatch.setattr(RigLink, "simulated", property(lambda self: False))   # as a real Mega reports itself
    status = rig.session.submit(rig.session.link.status).result()
    assert status.state & msg.DeviceState.POSITION_UNKNOWN   # the simulated device powers up not knowing it
    with pytest.raises(FailedStatus) as refused:
        re(bp.count([rig.length], 1))
    assert isinstance(refused.value.__cause__, PositionUnknown)
    assert "declare the zero from Python with `rig.declare_twist(0)`" in str(refused.value.__cause__)
    assert rec.events() == []
    rig.declare_twist(0)
    re(bp.count([rig.length], 1))
    assert len(rec.events()) == 1


def test_sampling_and_integration_settings_keep_a_sample_in_every_window(session):
    re, rec, rig = session
    re(bps.mv(rig.integration_time, 1.0, rig.sampling_period, 0.05))
    re(bp.count([rig.length], 1))
    assert len(rec.events()) == 1
    with pytest.raises(FailedStatus):
        re(bps.mv(rig.integration_time, 0.04))   # shorter than the sampling period: no sample guaranteed
    with pytest.raises(ValueError, match="shorter than"):
        connect("sim://", sampling_period_s=0.5, integration_time_s=0.5)


def test_load_is_declared_as_configuration_and_hangs_on_the_simulated_plant(session):
    re, rec, rig = session
    re(bp.count([rig], 1))
    light = rec.events()[-1]["data"]["rig-length"]
    re(bps.mv(rig.load, 150))
    re(bp.count([rig], 1))
    event, desc = rec.events()[-1], rec.of("descriptor")[-1]
    assert desc["configuration"]["rig"]["data"]["rig-load"] == 150
    assert desc["configuration"]["rig"]["data_keys"]["rig-load"]["units"] == "g"
    assert event["data"]["rig-length"] < light      # 500 g at power-up -> 150 g: the TSA contracts
    assert set(event["data"]) >= {"rig-length", "rig-resistance", "rig-step_position", "rig-device_time",
                                  "rig-twist", "rig-heater"}
    with pytest.raises(FailedStatus):
        re(bps.mv(rig.load, -1))


def test_the_rig_refuses_a_port_the_policy_does_not_allow():
    from tsa_bench.bench.ports import PortPolicyError

    with pytest.raises(PortPolicyError, match="only serial device paths"):
        connect("spy:///dev/ttyACM0")


def test_a_long_move_with_sampling_off_keeps_the_device_watchdog_fed(session):
    """60 s of motion with nothing coming back from the device: the link heartbeats on the
    simulated device's own clock, so its watchdog never trips mid-move."""
    re, rec, rig = session
    re(bps.mv(rig.twist, 60))
    re(bp.count([rig.length], 1))
    assert rig.session.link.fault == 0
    assert rec.events()[-1]["data"]["rig-length"] < 200       # 60 turns shorten the TSA a lot (mm)
    assert rig.session.position_steps == 60 * rig.session.link.steps_per_turn
