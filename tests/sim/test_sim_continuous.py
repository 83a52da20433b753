"""The simulated device at the ADS1115's limit: continuous sampling at 860 samples/s in
SAMPLE_BLOCK frames, resistance at the CS5513's own rate, periods the sensor or the line
cannot carry refused with their reason, and a run file that stores it all."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
import serial

import tsa_bench.transport  # noqa: F401  (registers sim://)
from tests import conformance_scenarios as sc
from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient, CommandRefused
from tsa_bench.plan import load_plan_text
from tsa_bench.protocol import msg
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.sim.sensors import CS5513_CONVERSION_S
from tsa_bench.store import RunWriter


def test_continuous_sampling_at_860_per_second_in_blocks():
    obs = sc.continuous_sampling(sc.Exchange(serial.serial_for_url("sim://?seed=1", timeout=0), settle_s=0))
    assert obs["log"][1][0] == ("ACK", 0x14, "OK", 16)
    assert obs["continuous"]
    assert obs["rate_per_s"] == pytest.approx(860, rel=1e-3)
    assert obs["blocks"] <= obs["samples"] / 6 + 2                 # six samples a frame
    assert obs["resistance_per_s"] == pytest.approx(1 / CS5513_CONVERSION_S, rel=0.05)   # 52.3 words/s


REPO = Path(__file__).resolve().parents[2]


def _client(url: str) -> BenchClient:
    client = BenchClient(serial.serial_for_url(url, timeout=0))
    client.connect(1.0)
    return client


def test_a_period_the_line_cannot_carry_is_refused_with_the_reason(tmp_path):
    text = (REPO / "configs" / "bench" / "sim.yaml").read_text()
    assert "baud: 250000" in text
    slow = tmp_path / "slow-line.yaml"
    slow.write_text(text.replace("baud: 250000", "baud: 115200"))
    client = _client(f"sim://?bench={slow}&seed=0")
    with pytest.raises(CommandRefused) as err:
        client.command(msg.SetSampling(0xFFFF, 1163))
    assert err.value.status == msg.Status.TOO_FAST_FOR_LINE
    assert "too_fast_for_line" in str(err.value) and "bytes/s" in str(err.value)
    assert client.command(msg.SetSampling(0xFFFF, 2326)).status == msg.Status.OK   # every second conversion
    with pytest.raises(CommandRefused, match="shorter than one ADS1115 conversion"):
        client.command(msg.SetSampling(0xFFFF, 1000))
    # a run at that period stops at once and says why
    plan = load_plan_text("name: fast\nload_g: 300\nsampling_period_s: 0.001163\nsteps:\n  - hold: {duration_s: 1}\n",
                          load_bench(slow).limits, "fast.yaml")
    stop = Runner(_client(f"sim://?bench={slow}&seed=0"), plan, load_bench(slow), [RunWriter(tmp_path / "r.h5")],
                  AutoOperator(), backend="sim", port_name="sim://").run()
    assert stop.exit_status == "failed"
    assert "too_fast_for_line" in stop.reason and "115200 baud" in stop.reason


def test_a_run_at_860_per_second_stores_every_sample(tmp_path):
    bench = load_bench(None)
    plan = load_plan_text("""name: fast
load_g: 300
sampling_period_s: 0.001163
defaults: {rate_turns_per_s: 3, accel_turns_per_s2: 30}
steps:
  - move_to: {turns: 2}
  - hold: {duration_s: 0.5}
  - heater: {voltage_V: 4}
  - hold: {duration_s: 0.2}
  - heater: {voltage_V: 0}
""", bench.limits, "fast.yaml")
    client = _client("sim://?seed=0")
    stop = Runner(client, plan, bench, [RunWriter(tmp_path / "fast.h5")], AutoOperator(),
                  backend="sim", port_name="sim://").run()
    assert stop.exit_status == "success", stop.reason
    assert stop.samples_lost == 0
    with h5py.File(tmp_path / "fast.h5") as f:
        t, counter = f["samples/t"][()], f["samples/counter"][()]
        resistance, heater = f["samples/resistance"][()], f["samples/heater_voltage"][()]
    assert np.all(np.diff(counter) == 1)
    assert np.median(np.diff(t)) == pytest.approx(1 / 860, abs=2e-6)
    assert np.all(np.isnan(resistance[heater > 0]))
    words = np.isfinite(resistance)
    assert 0 < words.sum() < len(t) / 10          # resistance only at the CS5513's ~52 words/s


def test_blocks_are_numbered_like_every_other_frame():
    """Each SAMPLE_BLOCK takes the next frame number (no gap for the samples inside it),
    so the host's link layer sees nothing lost or held back; a full block goes out at once."""
    client = BenchClient(serial.serial_for_url("sim://?seed=2", timeout=0))
    client.connect(1.0)
    client.command(msg.SetSampling(1, 1163))
    got = []
    while len(got) < 600:
        got += [m for m in client.poll() if isinstance(m, msg.Sample)]
    assert client.link.lost == 0 and client.link.restored == 0
    assert all(b.counter == a.counter + 1 for a, b in zip(got, got[1:]))
