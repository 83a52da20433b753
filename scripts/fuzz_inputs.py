#!/usr/bin/env python3
"""Generated bad inputs across every command: count tracebacks and hangs by family.

Mutates good files (tests/faults/mutations.py) - protocols, bench files, CSVs, run
files, model JSON, manipulator files, live sidecars - plus special files (FIFO,
directory, device, empty, missing), and runs the commands that read each of them
in-process (validate, run, effects, info, export, watch, report, fit, predict,
diagnose, import, manipulator), each under a time limit. A case passes when the
command exits with an allowed code (0 or 2; `run` and `watch` may also say 1) and no
exception escapes it; `validate` and `run` must agree on which protocols they refuse.
Prints per family: cases, exit codes, tracebacks, hangs, validate/run disagreements,
then the first few failures with the input kept for reproduction. Exit 0 when there
are no tracebacks, hangs or disagreements.

    PYTHONPATH=host python3 scripts/fuzz_inputs.py [--cases 2500] [--seed 0] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import resource
import shutil
import signal
import sys
import tempfile
import time
import traceback
from collections import Counter, defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from click.testing import CliRunner  # noqa: E402

from tests.faults.mutations import (  # noqa: E402
    CSV_OPS, JSON_OPS, RUN_OPS, TEXT_OPS, apply_csv, apply_json, apply_text, mutate_run, random_ops, write_text,
)
from tsa_bench.cli import main  # noqa: E402

TIME_LIMIT_S = 60
SMALL_PLAN = """name: small
load_g: 200
sampling_period_s: 0.1
defaults: {rate_turns_per_s: 2, accel_turns_per_s2: 20}
steps:
  - move_to: {turns: 5}
  - hold: {duration_s: 3}
  - prompt: {text: "hang 300 g", load_g: 300}
  - repeat: {count: 3, steps: [{move_by: {turns: 2}}, {hold: {duration_s: 1}}, {move_by: {turns: -2}}]}
  - heater: {voltage_V: 2}
  - hold: {duration_s: 2}
  - heater: {voltage_V: 0}
  - move_to: {turns: 0}
"""


class Hang(Exception):
    pass


def _alarm(signum, frame):
    raise Hang()


class Fuzzer:
    def __init__(self, work: Path, keep: Path | None) -> None:
        self.work, self.keep = work, keep
        self.runner = CliRunner()
        self.stats: dict[str, Counter] = defaultdict(Counter)
        self.failures: list[str] = []
        self.n = 0

    def case(self, family: str, args: list[str], allowed: tuple[int, ...] = (0, 2),
             inputs: tuple[Path, ...] = ()) -> int | None:
        """Run one command; count its outcome under ``family``; return the exit code."""
        self.n += 1
        st = self.stats[family]
        st["cases"] += 1
        signal.signal(signal.SIGALRM, _alarm)
        signal.alarm(TIME_LIMIT_S)
        t0 = time.monotonic()
        try:
            result = self.runner.invoke(main, args, catch_exceptions=True)
        except Hang:
            result = None
        finally:
            signal.alarm(0)
        if result is None or isinstance(result.exception, Hang):
            st["hangs"] += 1
            self._record(family, args, f"HANG after {time.monotonic() - t0:.0f} s", inputs)
            return None
        if result.exception is not None and not isinstance(result.exception, SystemExit):
            st["tracebacks"] += 1
            tb = "".join(traceback.format_exception(result.exception))[-1500:]
            self._record(family, args, tb, inputs)
            return None
        code = result.exit_code
        st[f"exit {code}"] += 1
        if code not in allowed:
            st["bad exit"] += 1
            self._record(family, args, f"exit {code}: {result.output[-500:]}", inputs)
        return code

    def _record(self, family: str, args: list[str], what: str, inputs: tuple[Path, ...]) -> None:
        kept = ""
        if self.keep is not None:
            d = self.keep / f"{len(self.failures):03d}-{family}"
            d.mkdir(parents=True, exist_ok=True)
            for p in inputs:
                if p.is_file():
                    shutil.copy(p, d / p.name)
            kept = f" (inputs in {d})"
        self.failures.append(f"[{family}] {' '.join(args)[:300]}{kept}\n{what}")


def prepare(work: Path) -> dict[str, Path]:
    """Good files to mutate: a small run, its CSV, a fitted model, a sidecar."""
    from tsa_bench.store.live import LiveSidecar  # noqa: F401

    good: dict[str, Path] = {}
    plan = work / "small.yaml"
    plan.write_text(SMALL_PLAN)
    good["plan"] = plan
    run = work / "good.h5"
    r = CliRunner().invoke(main, ["run", str(plan), "--output", str(run), "--seed", "1"])
    assert r.exit_code == 0, r.output
    good["run"] = run
    sweep = work / "sweep.h5"
    r = CliRunner().invoke(main, ["run", str(ROOT / "configs/protocols/twist-sweep-3ply.yaml"), "--output", str(sweep)])
    assert r.exit_code == 0, r.output
    good["sweep"] = sweep
    r = CliRunner().invoke(main, ["export", str(run), "--csv", "--out", str(work / "csv")])
    assert r.exit_code == 0, r.output
    good["csv"] = work / "csv" / "good.samples.csv"
    model = work / "model.json"
    r = CliRunner().invoke(main, ["fit", "polynomial", str(sweep), "--out", str(model)])
    assert r.exit_code == 0, r.output
    good["model"] = model
    pmodel = work / "preisach.json"
    r = CliRunner().invoke(main, ["fit", "preisach", str(sweep), "--levels", "5", "--out", str(pmodel)])
    assert r.exit_code == 0, r.output
    good["preisach"] = pmodel
    # a sidecar kept after the run ended
    import serial

    import tsa_bench.transport  # noqa: F401
    from tsa_bench.bench import load_bench
    from tsa_bench.device import BenchClient
    from tsa_bench.plan import load_plan
    from tsa_bench.runner import AutoOperator, Runner
    from tsa_bench.store import RunWriter

    bench = load_bench(None)
    port = serial.serial_for_url("sim://?seed=1", timeout=0.05)
    client = BenchClient(port, ack_timeout_s=bench.ack_timeout_s)
    client.connect(bench.boot_timeout_s)
    side_run = work / "side.h5"
    Runner(client, load_plan(plan, bench.limits), bench, [RunWriter(side_run), LiveSidecar(side_run, remove_at_end=False)],
           AutoOperator(), backend="sim", port_name="sim://").run()
    good["sidecar"] = work / "side.h5.live"
    return good


def special_files(work: Path) -> list[Path]:
    d = work / "special"
    d.mkdir()
    fifo = d / "fifo.h5"
    os.mkfifo(fifo)
    (d / "dir.h5").mkdir()
    (d / "empty.h5").write_bytes(b"")
    (d / "garbage.h5").write_bytes(os.urandom(4096))
    (d / "zero.h5").symlink_to("/dev/zero")
    (d / "null.h5").symlink_to("/dev/null")
    (d / "dangling.h5").symlink_to(d / "nowhere")
    return [fifo, d / "dir.h5", d / "empty.h5", d / "garbage.h5", d / "zero.h5", d / "null.h5", d / "dangling.h5",
            d / "missing.h5"]


def fuzz(f: Fuzzer, good: dict[str, Path], total: int, rng: random.Random) -> None:
    work = f.work / "cases"
    work.mkdir()
    protocols = [good["plan"], *sorted((ROOT / "configs/protocols").glob("*.yaml"))]
    benches = sorted((ROOT / "configs/bench").glob("*.yaml"))
    share = {"protocol": 0.22, "bench": 0.14, "csv": 0.12, "run file": 0.28, "model": 0.08, "manipulator": 0.06,
             "sidecar": 0.06, "options": 0.04}
    counts = {k: max(1, int(v * total)) for k, v in share.items()}
    k = 0

    def new(name: str) -> Path:
        nonlocal k
        k += 1
        return work / f"{k:05d}-{name}"

    for _ in range(counts["protocol"]):
        src = rng.choice(protocols)
        p = write_text(new(src.name), apply_text(src.read_text(), random_ops(rng, TEXT_OPS)))
        code_v = f.case("protocol", ["validate", str(p)], inputs=(p,))
        if src == good["plan"] and rng.random() < 0.25:  # run must refuse exactly what validate refuses
            out = new("run.h5")
            code_r = f.case("protocol", ["run", str(p), "--output", str(out), "--seed", "2"], (0, 1, 2), (p,))
            if code_v is not None and code_r is not None and (code_v == 2) != (code_r == 2):
                f.stats["protocol"]["run/validate"] += 1
                f.failures.append(f"[protocol] validate exit {code_v} but run exit {code_r}: {p}")
    for _ in range(counts["bench"]):
        src = rng.choice(benches)
        b = write_text(new(src.name), apply_text(src.read_text(), random_ops(rng, TEXT_OPS)))
        which = rng.random()
        if which < 0.5:
            f.case("bench", ["validate", str(good["plan"]), "--bench", str(b)], inputs=(b,))
        elif which < 0.9:
            f.case("bench", ["effects", "--bench", str(b)], inputs=(b,))
        elif "simavr" not in src.name:
            f.case("bench", ["run", str(good["plan"]), "--bench", str(b), "--output", str(new("run.h5"))],
                   (0, 1, 2), (b,))
    for _ in range(counts["csv"]):
        c = write_text(new("in.csv"), apply_csv(good["csv"].read_text(), random_ops(rng, CSV_OPS)))
        f.case("csv", ["import", str(c), "--out", str(new("imported.h5"))], inputs=(c,))
    for i in range(counts["run file"]):
        src = good["run"] if rng.random() < 0.7 else good["sweep"]
        r = mutate_run(src, new("run.h5"), random_ops(rng, RUN_OPS))
        roll = rng.random()
        if roll < 0.45:
            f.case("run file", ["info", str(r)], inputs=(r,))
        elif roll < 0.65:
            f.case("run file", ["export", str(r), "--csv", "--out", str(new("csv"))], inputs=(r,))
        elif roll < 0.75:
            f.case("run file", ["watch", str(r), "--once", "--wait", "0"], (0, 1, 2), (r,))
        elif roll < 0.83:
            f.case("run file", ["fit", "polynomial", str(r), "--out", str(new("m.json"))], inputs=(r,))
        elif roll < 0.91:
            f.case("run file", ["predict", str(good["model"]), str(r)], inputs=(r,))
        elif roll < 0.97:
            f.case("run file", ["report", str(r), "--out", str(new("report"))], inputs=(r,))
        else:
            f.case("run file", ["diagnose", str(r), "--out", str(new("diag")), "--max-causes", "1"], inputs=(r,))
    for _ in range(counts["model"]):
        src = good["model"] if rng.random() < 0.6 else good["preisach"]
        text = src.read_text()
        m = write_text(new("m.json"), apply_json(json.loads(text), text, random_ops(rng, JSON_OPS)))
        f.case("model", ["predict", str(m), str(good["sweep"])], inputs=(m,))
    man = ROOT / "configs/manipulator/thesis.yaml"
    for _ in range(counts["manipulator"]):
        m = write_text(new("man.yaml"), apply_text(man.read_text(), random_ops(rng, TEXT_OPS)))
        f.case("manipulator", ["manipulator", str(m)], inputs=(m,))
    raw = good["sidecar"].read_bytes()
    for _ in range(counts["sidecar"]):
        b = bytearray(raw)
        for _ in range(rng.randint(1, 4)):
            op = rng.random()
            if op < 0.4 and b:
                b[rng.randrange(min(len(b), 400))] = rng.randrange(256)
            elif op < 0.6:
                b[8:12] = rng.choice([b"\xff\xff\xff\x7f", b"\x00\x00\x00\x00", b"\x05\x00\x00\x00"])
            elif op < 0.8 and b:
                del b[rng.randrange(len(b)):]
            else:
                try:
                    head = json.loads(bytes(b[12:12 + int.from_bytes(b[8:12], "little")]) or b"{}") \
                        if b[:8] == b"TSALIVE1" else {}
                except ValueError:  # already broken by an earlier mutation
                    head = {}
                if isinstance(head, dict) and head:
                    key = rng.choice(sorted(head))
                    head[key] = rng.choice([None, "x", -1, 0, 2**70, [1], {"a": 1}, 1e308])
                    body = json.dumps(head).encode()
                    n0 = int.from_bytes(b[8:12], "little")
                    b = bytearray(b[:8] + len(body).to_bytes(4, "little") + body + b[12 + n0:])
        run_name = new("watched.h5")
        (run_name.with_name(run_name.name + ".live")).write_bytes(bytes(b))
        f.case("sidecar", ["watch", str(run_name), "--once", "--plain", "--wait", "0"], (0, 1, 2),
               (run_name.with_name(run_name.name + ".live"),))
    specials = special_files(f.work)
    options = [["run", str(good["plan"]), "--speed", "nan"], ["run", str(good["plan"]), "--speed", "-1"],
               ["run", str(good["plan"]), "--port", "spy://x?file=/tmp/x"],
               ["run", str(good["plan"]), "--port", "socket://localhost:1"],
               ["validate", str(good["plan"]), "--port", "rfc2217://h:1"],
               ["watch", str(good["run"]), "--interval", "nan"], ["watch", str(good["run"]), "--wait", "nan"],
               ["watch", str(good["run"]), "--interval", "-1"], ["fit", "preisach", str(good["run"]), "--levels",
                                                               "100000", "--out", str(work / "x.json")],
               ["fit", "polynomial", str(good["run"]), "--load-g", "nan", "--out", str(work / "y.json")],
               ["import", str(good["csv"]), "--out", str(good["run"])], ["import", str(good["csv"]), "--map", "=,,x"],
               ["diagnose", str(good["run"]), "--holdout", "fraction:nan"], ["diagnose", str(good["run"]),
                                                                          "--holdout", "run:99"]]
    for path in specials:
        for args in (["info", str(path)], ["export", str(path), "--csv", "--out", str(new("csv"))],
                     ["watch", str(path), "--once", "--wait", "0"], ["validate", str(path)],
                     ["validate", str(good["plan"]), "--bench", str(path)], ["import", str(path), "--out",
                                                                             str(new("i.h5"))],
                     ["predict", str(path), str(good["sweep"])], ["predict", str(good["model"]), str(path)],
                     ["manipulator", str(path)], ["report", str(path)], ["fit", "polynomial", str(path), "--out",
                                                                         str(new("m.json"))]):
            f.case("special files", args, (0, 1, 2) if args[0] == "watch" else (0, 2))
    for args in options * max(1, counts["options"] // len(options)):
        f.case("options", args, (0, 1, 2) if args[0] in ("run", "watch", "diagnose") else (0, 2))


def main_() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=2500, help="about this many generated inputs (default 2500)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--keep", type=Path, default=None, help="copy the inputs of failing cases here")
    args = ap.parse_args()
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = 6 * 1024**3
    if hard == resource.RLIM_INFINITY or hard > limit:  # a memory blow-up is a finding, not a dead machine
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    with tempfile.TemporaryDirectory(prefix="tsa-fuzz-") as d:
        f = Fuzzer(Path(d), args.keep)
        good = prepare(Path(d))
        t0 = time.monotonic()
        fuzz(f, good, args.cases, random.Random(args.seed))
        wall = time.monotonic() - t0
    keys = ["cases", "exit 0", "exit 1", "exit 2", "tracebacks", "hangs", "bad exit", "run/validate"]
    print(f"{'family':<15}" + "".join(f"{k:>13}" for k in keys))
    total = Counter()
    for family, st in f.stats.items():
        total.update(st)
        print(f"{family:<15}" + "".join(f"{st.get(k, 0):>13}" for k in keys))
    print(f"{'all':<15}" + "".join(f"{total.get(k, 0):>13}" for k in keys))
    print(f"{f.n} cases in {wall:.0f} s; tracebacks {total['tracebacks']}, hangs {total['hangs']}, "
          f"bad exit codes {total['bad exit']}, validate/run disagreements {total['run/validate']}")
    for text in f.failures[:15]:
        print("\n" + text)
    return 0 if not (total["tracebacks"] or total["hangs"] or total["bad exit"] or
                     total["run/validate"]) else 1


if __name__ == "__main__":
    sys.exit(main_())
