"""A run over a real serial link (a pseudo-terminal through the relay to the simulated
bench served on another pseudo-terminal): bytes arrive when they arrive."""

from __future__ import annotations

import sys

import h5py
import numpy as np
import pytest
import serial

from tests.faults.checks import check_rows_against_device
from tests.faults.ptybench import quick_bench, relayed_sim
from tests.faults.relay import CAMPAIGN, LinkFaults
from tests.runner.helpers import plan_from_text
from tests.runner.test_reliability import SHORT
from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.store import RunWriter

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="needs a POSIX pty")


def _run_over(relay, bench, plan, path):
    with serial.Serial(relay.path, bench.baud, timeout=0.05) as port:
        client = BenchClient(port, ack_timeout_s=bench.ack_timeout_s, watchdog_s=bench.watchdog_s)
        client.connect(bench.boot_timeout_s)
        return Runner(client, plan, bench, [RunWriter(path)], AutoOperator(), backend="serial",
                      port_name=relay.path).run()


def test_set_up_commands_are_no_queue_underrun_over_a_real_link(tmp_path):
    """The QUEUE_EMPTY that follows the set-up commands arrives, over a real link, after
    the first plan segment was sent; it is not an underrun (it was reported as one at
    t ~ 0.02 s in every run). Any underrun recorded names the plan segment it followed."""
    bench = load_bench(quick_bench(tmp_path))
    plan = plan_from_text(SHORT)
    with relayed_sim(quick_bench(tmp_path)) as relay:
        stop = _run_over(relay, bench, plan, tmp_path / "r.h5")
    assert stop.exit_status == "success", stop.reason
    with h5py.File(tmp_path / "r.h5") as f:
        events = f["events"][()]
        first_end = f["segments"]["t_end"][0]
    underruns = events[events["kind"] == b"queue_underrun"]
    assert all(b"after segment" in d for d in underruns["detail"])
    assert not np.any(underruns["t"] < first_end), underruns


def test_campaign_faults_over_a_real_link(tmp_path):
    bench = load_bench(quick_bench(tmp_path))
    plan = plan_from_text(SHORT)
    with relayed_sim(quick_bench(tmp_path), LinkFaults(to_host=CAMPAIGN, to_device=CAMPAIGN, seed=21)) as relay:
        stop = _run_over(relay, bench, plan, tmp_path / "r.h5")
        device_samples = relay.link.device_frames.samples()
    assert stop.exit_status == "success", stop.reason
    counts = check_rows_against_device(tmp_path / "r.h5", device_samples)
    assert counts["rows"] > 100
