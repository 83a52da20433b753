"""Session fixtures for the data hand-off tests: one simulated run of every shipped protocol."""

from __future__ import annotations

from pathlib import Path

import pytest
import serial

import tsa_bench.transport  # noqa: F401  (registers sim://)
from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient
from tsa_bench.plan import load_plan
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.store import RunWriter

ROOT = Path(__file__).resolve().parents[2]
PROTOCOLS = sorted((ROOT / "configs" / "protocols").glob("*.yaml"))


def simulate(protocol: Path, out: Path, seed: int = 2, consumers: tuple = ()) -> Path:
    """Run ``protocol`` on the default simulated bench (or the preset its metadata names, for a
    protocol of one string) as fast as possible; return the run file."""
    bench = load_bench(None)
    plan = load_plan(protocol, bench.limits)
    url = f"sim://?seed={seed}"
    if "bench" in plan.metadata:
        preset = ROOT / "configs" / "bench" / f"{plan.metadata['bench']}.yaml"
        bench = load_bench(preset)
        url += f"&bench={preset}"
    port = serial.serial_for_url(url, timeout=0.05)
    try:
        client = BenchClient(port, ack_timeout_s=bench.ack_timeout_s)
        client.connect(bench.boot_timeout_s)
        stop = Runner(client, plan, bench, [RunWriter(out), *consumers], AutoOperator(), backend="sim",
                      port_name="sim://").run()
    finally:
        port.close()
    assert stop.exit_status == "success", stop.reason
    return out


@pytest.fixture(scope="session")
def protocol_runs(tmp_path_factory) -> dict[str, Path]:
    """{protocol name: run file} for every protocol in configs/protocols (~12 s in all)."""
    d = tmp_path_factory.mktemp("protocol_runs")
    return {p.stem: simulate(p, d / f"{p.stem}.h5") for p in PROTOCOLS}
