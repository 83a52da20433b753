"""The link layer under a fault-injecting relay: drops, corruption, duplicates, swaps,
stalls and a cut, between the host and the simulated device or the firmware core.

Every run either succeeds or fails cleanly; every stored row is a sample the device
sent, unchanged, once and in order; ``samples_lost`` equals the counter gaps. (The
heavy campaign is scripts/link_campaign.py; these runs are its small version.)
"""

from __future__ import annotations

import pytest

from tests.faults.checks import check_rows_against_device
from tests.faults.relay import CAMPAIGN, Faults, FaultyPort, LinkFaults
from tests.runner.helpers import open_sim, plan_from_text, run_plan
from tests.runner.test_reliability import SHORT, assert_executed_once_in_order

CLEAN_FAILURES = ("watchdog", "no ACK", "lost the connection", "silent")


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_campaign_faults_both_ways_store_only_what_the_device_sent(tmp_path, seed):
    plan = plan_from_text(SHORT)
    port = FaultyPort(open_sim(seed), LinkFaults(to_host=CAMPAIGN, to_device=CAMPAIGN, seed=seed))
    stop, client, path = run_plan(plan, tmp_path, port=port)
    assert stop.exit_status == "success", stop.reason
    stats = port.link.stats["to_host"]
    assert stats["dropped"] and stats["duplicated"] and stats["swapped"] and stats["flipped"]
    counts = check_rows_against_device(path, port.link.device_frames.samples())
    assert counts["gaps"] > 0 and client.link.duplicates > 0 and client.link.restored > 0
    assert stop.samples_lost == counts["gaps"]


def test_duplicated_and_swapped_frames_alone_lose_nothing(tmp_path):
    """Duplicates are dropped and swapped pairs put back in order: every sample is kept."""
    plan = plan_from_text(SHORT)
    faults = Faults(duplicate=0.05, swap=0.05)
    port = FaultyPort(open_sim(4), LinkFaults(to_host=faults, to_device=faults, seed=4))
    stop, client, path = run_plan(plan, tmp_path, port=port)
    assert stop.exit_status == "success", stop.reason
    counts = check_rows_against_device(path, port.link.device_frames.samples())
    assert counts["gaps"] == 0 and stop.samples_lost == 0 and counts["rows"] == counts["sent"]
    assert client.link.duplicates >= port.link.stats["to_host"]["duplicated"] > 10
    assert_executed_once_in_order(plan, path, end_tolerance_s=0.8)


@pytest.mark.parametrize("stall_s", [0.5, 1.5])
def test_a_stall_shorter_than_the_watchdog_does_not_fail_the_run(tmp_path, stall_s):
    """Nothing passes either way for ``stall_s`` of device time, while moving and holding.
    The device hears nothing for the stall plus up to one heartbeat period (0.25 s): below
    its 2 s watchdog the run goes on, and the host never gives up first."""
    plan = plan_from_text(SHORT)
    port = FaultyPort(open_sim(5), LinkFaults(stalls=((4.0, stall_s), (20.0, stall_s)), seed=5))
    stop, client, path = run_plan(plan, tmp_path, port=port)
    assert stop.exit_status == "success", stop.reason
    check_rows_against_device(path, port.link.device_frames.samples())
    assert_executed_once_in_order(plan, path, end_tolerance_s=0.8)


@pytest.mark.parametrize("stall_s", [1.9, 3.0])
def test_a_stall_reaching_the_watchdog_fails_cleanly_with_the_watchdog_named(tmp_path, stall_s):
    """Once the device has heard nothing for its watchdog period it stops motor and
    heater itself; the run then ends failed with that fault, keeping its data (the host
    kept retransmitting meanwhile: it never gives up before the device would)."""
    plan = plan_from_text(SHORT)
    port = FaultyPort(open_sim(6), LinkFaults(stalls=((4.0, stall_s),), seed=6))
    stop, client, path = run_plan(plan, tmp_path, port=port)
    assert stop.exit_status == "failed" and "watchdog" in stop.reason, stop.reason
    check_rows_against_device(path, port.link.device_frames.samples())


def test_a_cut_line_fails_cleanly_and_keeps_the_data(tmp_path):
    plan = plan_from_text(SHORT)
    port = FaultyPort(open_sim(7), LinkFaults(to_host=CAMPAIGN, to_device=CAMPAIGN, cut_at_s=15.0, seed=7))
    stop, client, path = run_plan(plan, tmp_path, port=port)
    assert stop.exit_status == "failed" and "lost the connection" in stop.reason, stop.reason
    counts = check_rows_against_device(path, port.link.device_frames.samples())
    assert counts["rows"] > 50
