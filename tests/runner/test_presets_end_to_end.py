"""Thesis experiments through the whole stack on their matching simulated benches: the
run file shows the thesis magnitudes (issue 4), not only the plant in isolation."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import serial

import tsa_bench.transport  # noqa: F401
from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient
from tsa_bench.plan import load_plan
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.store import RunWriter

ROOT = Path(__file__).resolve().parents[2]


def run(protocol: str, bench_file: str, out: Path) -> dict:
    bench = load_bench(ROOT / "configs" / "bench" / bench_file)
    plan = load_plan(ROOT / "configs" / "protocols" / protocol, bench.limits)
    port = serial.serial_for_url(f"sim://?bench={bench.path}&seed=3", timeout=0.05)
    client = BenchClient(port, ack_timeout_s=bench.ack_timeout_s)
    client.connect(bench.boot_timeout_s)
    stop = Runner(client, plan, bench, [RunWriter(out)], AutoOperator(), backend="sim", port_name="sim://").run()
    port.close()
    assert stop.exit_status == "success", stop.reason
    with h5py.File(out) as f:
        return {name: ds[()] for name, ds in f["samples"].items()}


def settled(d: dict, turns: float, load_N: float, heater_V: float = 0.0) -> float:
    """Median length over the last 30 s of holds at a twist level (mm)."""
    sel = (np.isclose(d["turns"], turns) & np.isclose(d["load"], load_N, rtol=1e-3)
           & np.isclose(d["heater_voltage"], heater_V) & (d["motor_moving"] == 0))
    t = d["t"][sel]
    assert len(t), f"no samples at {turns} turns, {load_N} N, {heater_V} V"
    return float(np.median(d["length"][sel][t >= t.max() - 30]))


def test_quasi_static_scheme1_contracts_28_to_21_cm(tmp_path):
    d = run("quasi-static-self-sensing.yaml", "sim-scheme1.yaml", tmp_path / "qs.h5")
    for load_g in (450, 550):
        w = load_g * 9.80665e-3
        at20, at55 = settled(d, 20, w), settled(d, 55, w)
        # thesis 2.5.1: "from 28 cm to 21 cm", "over 25% contraction"; +-1 cm for read-off figures
        assert abs(at20 - 280) < 10 and abs(at55 - 210) < 10
        assert (at20 - at55) / at55 > 0.25
    # heavier load, longer TSA: compared at the one visit of 55 turns (the 40-turn level is read on
    # the way back, where the calibrated preset's load-dependent twist play can cancel the 0.4 mm
    # the UHMWPE-dominated pair stretches; configs/thesis/calibration.yaml)
    assert settled(d, 55, 550 * 9.80665e-3) > settled(d, 55, 450 * 9.80665e-3)


def test_twist_then_heat_4ply_adds_about_12_percent(tmp_path):
    d = run("twist-heat-4ply.yaml", "sim-4ply.yaml", tmp_path / "th.h5")
    w = 250 * 9.80665e-3
    cold = settled(d, 81, w, 0.0)
    hot = settled(d, 81, w, float(d["heater_voltage"].max()))
    # thesis 2.4.3: 14.1 % further contraction from heating after 81 turns (4-ply, 250 g); the
    # calibrated preset gives about 11.5 %: the 4-ply records pull against each other
    # (configs/thesis/calibration.yaml, ch2.strain.4ply_250g_thermal)
    assert 0.09 < (cold - hot) / hot < 0.15
