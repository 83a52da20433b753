"""One set of scripted exchanges against the simulated device (the executable
specification) and the firmware ELF in simavr: the observable results must agree.
Where they differ one of them is wrong (this suite found that the firmware lost
sample slots while the CS5513 settled, and that the simulated device had no CS5513
timing at all; both were fixed)."""

from __future__ import annotations

import pytest

from tests import conformance_scenarios as sc
from tests.simavr.conftest import sim_port, simavr_port

def run_both(scenario, firmware_dir, **settings):
    """The scenario on the simulated device, then on simavr waiting at each step for as many
    replies as the simulated device gave (a condition, not a quiet window: a busy machine
    only slows the emulated CPU)."""
    sim_ex = sc.Exchange(sim_port(), settle_s=0)
    sim = scenario(sim_ex)
    with simavr_port(firmware_dir, **settings) as (port, bench):
        fil = scenario(sc.Exchange(port, settle_s=0.05, follows=sim_ex))
    assert bench.summary is not None and not bench.summary["crashed"], bench.stderr_text
    return sim, fil, bench.summary


def assert_same_log(fil_log, sim_log):
    assert len(fil_log) == len(sim_log)
    for i, (fil, sim) in enumerate(zip(fil_log, sim_log)):
        assert fil == sim, f"exchange {i}: firmware in simavr {fil} != simulated device {sim}"


def test_every_command_refusal_duplicate_and_full_queue(firmware_dir):
    sim, fil, summary = run_both(sc.every_command_and_refusal, firmware_dir)
    assert_same_log(fil, sim)
    statuses = {r[2] for step in sim for r in step if r[0] == "ACK"}
    assert {"OK", "QUEUE_FULL", "BAD_ARGUMENT", "LIMIT_EXCEEDED", "UNKNOWN_MESSAGE", "BAD_LENGTH"} <= statuses
    assert summary["violations"]["uart_rx_overrun"] == 0


def test_corrupt_frames_are_dropped_without_losing_the_next(firmware_dir):
    sim, fil, _ = run_both(sc.corrupt_frames, firmware_dir)
    assert_same_log(fil, sim)
    assert sim[1:4] == [[], [], []]                      # no answer to corrupt frames
    assert [r[0] for r in sim[4]] == ["ACK", "QUEUE_STATUS"]  # the valid one after garbage


def test_stop_during_a_move(firmware_dir):
    sim, fil, summary = run_both(sc.stop_during_move, firmware_dir)
    assert_same_log(fil["log"], sim["log"])
    for obs in (sim, fil):
        assert obs["stopped_mid_move"] and obs["frozen_after"] and not obs["segment_done"]
    assert 1600 < summary["steps"]["position"] < 32_000     # the A4988 saw it stop
    assert summary["violations"]["step_pulse_width"] == summary["violations"]["dir_setup"] == 0


def test_watchdog_trip_stops_heater_and_latches(firmware_dir):
    sim, fil, _ = run_both(sc.watchdog_trip, firmware_dir, host_gone_ms=300)
    assert_same_log(fil["log"], sim["log"])
    assert fil["faults"] == sim["faults"] == [("EVENT", "FAULT", 3, int(sc.msg.Fault.WATCHDOG))]
    for obs in (sim, fil):
        assert obs["heater_on_before"] and obs["heater_off_after"]
    assert [r[2] for r in sim["log"][4] if r[0] == "ACK"] == ["BAD_STATE"]


def test_heater_sense_interlock_and_counter_continuity(firmware_dir):
    sim, fil, summary = run_both(sc.heater_sense_interlock, firmware_dir)
    assert_same_log(fil["log"], sim["log"])
    for obs in (sim, fil):
        assert obs["continuous"] and obs["heated_not_measured"] and obs["measured_before_heating"]
    # ~80 ms of CS5513 settling after the current returns: 3-4 slots at 20 ms
    assert 2 <= fil["samples_until_resistance_back"] <= 5
    assert abs(fil["samples_until_resistance_back"] - sim["samples_until_resistance_back"]) <= 1
    assert summary["violations"]["heater_sense_interlock"] == 0


@pytest.mark.parametrize("scenario", [sc.short_period])
def test_period_shorter_than_a_conversion_keeps_every_slot(firmware_dir, scenario):
    sim, fil, _ = run_both(scenario, firmware_dir)
    assert_same_log(fil["log"], sim["log"])
    assert sim["continuous"] and fil["continuous"]
    assert 0.3 < fil["measured_fraction"] < 0.7
    assert abs(fil["measured_fraction"] - sim["measured_fraction"]) < 0.15


def test_continuous_sampling_at_the_ads1115_limit(firmware_dir):
    """Sampling period 1163 us: the ADS1115 in continuous mode paced by ALERT/RDY, 860
    samples/s in SAMPLE_BLOCK frames with no counter gap, resistance at the CS5513's own
    rate (19125 us a word in the harness: 52.3 per second), on both backends."""
    sim, fil, summary = run_both(sc.continuous_sampling, firmware_dir)
    assert_same_log(fil["log"], sim["log"])
    for obs in (sim, fil):
        assert obs["continuous"] and obs["samples"] > 700
        assert obs["rate_per_s"] == pytest.approx(860, rel=0.01)
        assert obs["blocks"] <= obs["samples"] / 6 + 2
    assert sim["resistance_per_s"] == pytest.approx(52.3, rel=0.05)
    assert fil["resistance_per_s"] == pytest.approx(sim["resistance_per_s"], rel=0.25)
    assert summary["adc"]["ads1115_rdy_pulses"] >= fil["samples"]
    assert summary["violations"]["uart_rx_overrun"] == 0


def test_stop_at_speed_decelerates_at_the_limit(firmware_dir):
    """STOP at 16,000 steps/s: both decelerate at the device's limit (~400 steps) to the
    position EVENT stopped announces; the A4988 agrees. (Before: an instant stop at any
    speed, where a real motor loses steps.)"""
    sim, fil, summary = run_both(sc.stop_at_speed, firmware_dir)
    assert_same_log(fil["log"], sim["log"])
    for obs in (sim, fil):
        assert obs["stopped_once"] and obs["ends_at_rest_value"]
        assert 380 <= obs["coasted_steps"] <= 600          # 400 at the limit, from <= 10 ms before
    assert summary["steps"]["position"] == fil["rest"]                  # the A4988 ended where announced
    assert all(v == 0 for v in summary["violations"].values()), summary["violations"]


def test_heater_applied_voltage_reported_alike(firmware_dir):
    sim, fil, _ = run_both(sc.heater_applied, firmware_dir)
    assert_same_log(fil["log"], sim["log"])
    assert fil["reported_mV"] == sim["reported_mV"] and fil["off_mV"] == sim["off_mV"] == 0


def test_host_lost_heater_off_at_the_watchdog_motor_and_sense_released_later(firmware_dir):
    """A host that vanishes while sampling with the heater on: the heater is off within
    20 ms of the watchdog period, and fault_release_ms later the motor is de-energized
    and the sense current is off, sampling stops; both backends alike. (Before: sampling
    and the 50 mA sense current went on forever, the motor stayed energized.)"""
    scenario = sc.fault_release_with_heater
    sim, fil, summary = run_both(scenario, firmware_dir, host_gone_ms=300)
    assert_same_log(fil["log"], sim["log"])
    for obs in (sim, fil):
        assert obs["fault_code"] == obs["released_code"] == int(sc.msg.Fault.WATCHDOG)
        assert abs(obs["release_after_fault_s"] - 10.0) < 0.05 and not obs["samples_after_release"]
    tripped = fil["fault_t_s"] + summary["clock_zero_s"]                 # device time of the watchdog trip
    assert 0 <= summary["heater"]["last_off_s"] - tripped < 0.02
    released = summary["drive"]["last_disable_s"]
    assert 10.0 <= released - tripped < 10.01
    assert summary["drive"]["disables"] == 1 and not summary["drive"]["sense_on"]   # (CLEAR_QUEUE re-energized it)
    assert abs(summary["drive"]["last_sense_off_s"] - released) < 0.01
