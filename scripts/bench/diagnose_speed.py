#!/usr/bin/env python3
"""Speed of `tsa-bench diagnose` on a lifetime run (596 cycles, ~100k samples).

Runs the lifetime protocol through the simulated bench (plant + simulated device +
codec + runner + HDF5 writer) with the judged model's plant (default: the baseline
returned by ``tsa_bench.analysis.load_model(None)``) plus ONE hidden effect switched on
at its library default, then times ``diagnose`` on that file and prints the seconds
(target < 60 s on a 2-core machine) and what was named.

    python scripts/bench/diagnose_speed.py [--effect NAME] [--protocol P.yaml] [--model BENCH.yaml]
                                           [--seed N] [--keep DIR] [--run RUN.h5] [--times N]

``--times 10`` runs the lifetime protocol with ten times its cycles (5,960 cycles, 27.6 h,
995k samples): the day of data diagnose must handle in 30 s and 500 MiB. Keep the file
(``--keep DIR``) and time the command itself on it::

    /usr/bin/time -v tsa-bench diagnose DIR/hidden.h5 --seed 1

:func:`simulate_run` and :func:`with_hidden_effect` are reused (imported by path) by
diagnose_power.py and tests/report_diagnose.
"""

from __future__ import annotations

import argparse
import copy
import sys
import resource
import tempfile
import time
import urllib.parse
from collections.abc import Mapping
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
#: Effects preferred as the hidden one, in order (the first the judged model leaves off is used).
PREFERRED = ("resistance_transient_decay", "resistance_creep", "length_creep", "twist_hysteresis",
             "resistance_temperature", "load_dependence", "missed_steps", "thermal_dynamics")


def plant_of(model: Mapping) -> dict:
    """The plant mapping of a model (accepts a whole bench mapping too)."""
    return copy.deepcopy(dict(model["plant"] if "plant" in model else model))


def effects_off(model: Mapping) -> list[str]:
    """Library effects the model leaves off (disabled or absent)."""
    from tsa_bench.sim.effects import describe_effects
    fx = plant_of(model).get("effects") or {}
    return [e["name"] for e in describe_effects()
            if not (isinstance(fx.get(e["name"]), Mapping) and fx[e["name"]].get("enabled", True))]


def with_hidden_effect(model: Mapping, effect: str, params: Mapping | None = None) -> dict:
    """A copy of the model's plant with ``effect`` switched on (library defaults unless ``params``)."""
    plant = plant_of(model)
    fx = dict(plant.get("effects") or {})
    cfg = dict(fx.get(effect) or {})
    cfg["enabled"] = True
    cfg.update(params or {})
    fx[effect] = cfg
    plant["effects"] = fx
    return plant


def simulate_run(plant: Mapping, protocol: str | Path, out_path: str | Path, seed: int = 1) -> Path:
    """Run ``protocol`` on the simulated bench whose plant is ``plant``; write and return the run file."""
    import serial

    import tsa_bench.transport  # noqa: F401  (registers sim://)
    from tsa_bench.bench import load_bench
    from tsa_bench.device import BenchClient
    from tsa_bench.plan import load_plan
    from tsa_bench.runner import AutoOperator, Runner
    from tsa_bench.store import RunWriter

    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    bench_doc = yaml.safe_load((ROOT / "configs" / "bench" / "sim.yaml").read_text())
    bench_doc["name"] = "simulated bench with hidden effects (diagnose test data)"
    bench_doc["plant"] = dict(plant)
    bench_doc["plant"]["seed"] = seed
    bench_path = out_path.with_suffix(".bench.yaml")
    bench_path.write_text(yaml.safe_dump(bench_doc, sort_keys=False))
    bench = load_bench(bench_path)
    plan = load_plan(protocol, bench.limits)
    url = "sim://?" + urllib.parse.urlencode({"bench": str(bench_path.resolve()), "seed": str(seed)})
    port = serial.serial_for_url(url, timeout=0.05)
    try:
        client = BenchClient(port, ack_timeout_s=bench.ack_timeout_s)
        client.connect(bench.boot_timeout_s)
        stop = Runner(client, plan, bench, [RunWriter(out_path)], AutoOperator(), backend="sim",
                      port_name=url).run()
    finally:
        port.close()
    if stop.exit_status != "success":
        raise RuntimeError(f"simulated run of {protocol} ended {stop.exit_status}: {stop.reason}")
    return out_path


def scaled_lifetime(protocol: Path, times: int, where: Path) -> Path:
    """The lifetime protocol with ``times`` times its cycles, written into ``where``."""
    text = Path(protocol).read_text()
    if "count: 596" not in text or times < 1:
        sys.exit(f"diagnose_speed: --times needs the lifetime protocol (repeat count 596) and N >= 1, got {protocol}")
    where.mkdir(parents=True, exist_ok=True)
    out = where / f"lifetime-x{times}.yaml"
    out.write_text(text.replace("name: lifetime", f"name: lifetime-x{times}").replace("count: 596",
                                                                                      f"count: {596 * times}"))
    return out


def verdict(effect: str | None, result) -> str:
    if effect is None:
        return "OK (clean)" if result.verdict == "explained" else "FALSE ALARM"
    return "OK" if result.causes[:1] == [effect] else "MISSED"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--effect", default=None, help="hidden effect (default: first of %s off in the model)"
                    % ", ".join(PREFERRED[:3]))
    ap.add_argument("--protocol", type=Path, default=ROOT / "configs" / "protocols" / "lifetime.yaml")
    ap.add_argument("--model", default=None, help="judged model (default: the engine's baseline)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--keep", type=Path, default=None, help="keep the run file and report in this directory")
    ap.add_argument("--run", type=Path, default=None,
                    help="diagnose this run file (made by an earlier --keep) instead of simulating one")
    ap.add_argument("--times", type=int, default=1,
                    help="with the lifetime protocol: N times its cycles (10: a day of data, 995k samples)")
    ap.add_argument("--clean", action="store_true",
                    help="hide nothing: the judged model's own effects only (a named cause is a false alarm)")
    args = ap.parse_args()
    try:
        from tsa_bench.analysis import diagnose, load_model
    except ImportError as exc:
        sys.exit(f"diagnose_speed: the engine tsa_bench.analysis is missing ({exc})")
    from tsa_bench.store import read_run

    model = load_model(args.model)
    off = effects_off(model)
    effect = None if args.clean else args.effect or next((e for e in PREFERRED if e in off), None)
    if not args.clean and (effect is None or effect not in off):
        sys.exit(f"diagnose_speed: effect {effect!r} is not off in the judged model (off: {off})")
    with tempfile.TemporaryDirectory() as tmp:
        where = args.keep or Path(tmp)
        if args.times != 1:
            args.protocol = scaled_lifetime(args.protocol, args.times, where)
        t0 = time.perf_counter()
        truth = plant_of(model) if args.clean else with_hidden_effect(model, effect)
        path = args.run or simulate_run(truth, args.protocol, where / "hidden.h5", args.seed)
        t_sim = time.perf_counter() - t0
        t0 = time.perf_counter()
        runs = [read_run(path)]
        t_read = time.perf_counter() - t0
        t0, c0 = time.perf_counter(), time.process_time()
        result = diagnose(runs, model, None, seed=args.seed)
        t_diag, c_diag = time.perf_counter() - t0, time.process_time() - c0
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        t0 = time.perf_counter()
        from tsa_bench.report.diagnose_report import write_json, write_report
        write_report(result, runs, where / "report")
        write_json(result, where / "report" / "diagnose.json")
        t_rep = time.perf_counter() - t0
    n = len(runs[0])
    print(f"data        {args.run or args.protocol.name}: {n} samples, hidden effect {effect or 'none (clean)'} "
          f"(simulated in {t_sim:.1f} s, read in {t_read:.2f} s)")
    print(f"diagnose    {t_diag:.1f} s wall, {c_diag:.1f} s CPU (target <= 60 s at 1x, <= 30 s at 10x; wall > CPU "
          f"means a shared, busy "
          f"machine), peak RSS {peak:.0f} MiB -> {result.summary[:150]} [{verdict(effect, result)}]")
    print(f"report      {t_rep:.1f} s (report.txt + figures + JSON)")
    print(f"total       {t_diag + t_read + t_rep:.1f} s for read + diagnose + report")


if __name__ == "__main__":
    main()
