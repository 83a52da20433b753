"""Done-when of issue 31: a twist scan made with the RunEngine and the same scan made as a
YAML protocol, on the same simulated seed, give the same length and resistance readings at
the same twists."""

from __future__ import annotations

import bluesky.plan_stubs as bps
import bluesky.plans as bp
import numpy as np
import serial

from tests.bluesky.helpers import SCAN_PROTOCOL, SCAN_TURNS, connect, fsum_mean, make_re
from tsa_bench import transport  # noqa: F401  (registers sim://)
from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient
from tsa_bench.plan import load_plan
from tsa_bench.runner import AutoOperator, Runner


class _Keep:
    def __init__(self) -> None:
        self.blocks, self.segments, self.stop = [], [], None

    def on_start(self, start): ...
    def on_event(self, event): ...
    def on_samples(self, block): self.blocks.append(block)
    def on_segment(self, segment): self.segments.append(segment)
    def on_stop(self, stop): self.stop = stop


def _protocol_readings(tmp_path, seed: int) -> list[tuple[float, float, float]]:
    """(twist, mean length, mean resistance) of each hold of the protocol run by the runner."""
    bench = load_bench()
    path = tmp_path / "twist-scan.yaml"
    path.write_text(SCAN_PROTOCOL)
    plan = load_plan(path, bench.limits)
    port = serial.serial_for_url(f"sim://?seed={seed}", baudrate=bench.baud, timeout=0.05)
    try:
        client = BenchClient(port, ack_timeout_s=bench.ack_timeout_s, watchdog_s=bench.watchdog_s)
        client.connect(bench.boot_timeout_s)
        keep = _Keep()
        Runner(client, plan, bench, [keep], AutoOperator(), backend="sim", port_name="sim://").run()
    finally:
        port.close()
    assert keep.stop.exit_status == "success"
    cols = {k: np.concatenate([b.columns[k] for b in keep.blocks]) for k in ("turns", "length", "resistance",
                                                                           "segment")}
    out = []
    for seg in keep.segments:
        if seg.kind == "hold":
            m = cols["segment"] == seg.index
            assert m.sum() >= 4     # the 0.5 s hold's samples at 0.1 s
            out.append((float(cols["turns"][m][-1]), fsum_mean(cols["length"][m]), fsum_mean(cols["resistance"][m])))
    return out


def test_a_runengine_scan_reads_what_the_same_yaml_protocol_records(tmp_path):
    re, rec = make_re()
    rig = connect("sim://?seed=7", integration_time_s=0.5, sampling_period_s=0.1)
    try:
        re(bps.mv(rig.load, 200, rig.twist.velocity, 3.33, rig.twist.acceleration, 50))
        re(bp.scan([rig.length, rig.resistance], rig.twist, 0, 40, 9))
    finally:
        rig.close()
    scanned = [(e["data"]["rig-twist"], e["data"]["rig-length"], e["data"]["rig-resistance"]) for e in rec.events()]
    recorded = _protocol_readings(tmp_path, seed=7)
    assert [t for t, _, _ in recorded] == SCAN_TURNS
    assert scanned == recorded       # exactly: the same samples, reduced the same way
    # and the readings are not trivially equal: twisting changed both quantities
    assert len({round(x[1], 3) for x in scanned}) == 9 and len({round(x[2], 4) for x in scanned}) == 9
