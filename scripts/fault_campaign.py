#!/usr/bin/env python3
"""Fault campaign: runs killed at the worst instants, then recovered; counted.

Families (each a subcommand; ``all`` runs the first two):

* ``kill-writes``: a whole ``tsa-bench run`` (quasi-static-self-sensing at --speed 400 on the
  simulated bench) is first run to the end under strace to count its ``pwrite64`` calls,
  then run again and SIGKILLed on entering every ``--every``-th one (``strace -f -e
  trace=pwrite64 -e inject=pwrite64:signal=KILL:when=N``): a kill that depends on nothing
  inside the writer. The HDF5 call each write happens in is named from ``strace -k`` stacks.
* ``kill-phases``: the writer driven by tests/store/kill_driver.py (the real RunWriter and
  journal, synthetic documents), killed inside flushes and appends: on entering writes
  made inside ``H5Fflush`` or a column append (``H5Dwrite``, ``H5Dset_extent``), spread over
  the run, and on entering the writer's K-th column append and K-th file flush.
* ``link``: the link trials (relay with swapped, delayed frames; two CPU-burning processes
  beside the run) live in scripts/link_campaign.py; this runs it with the arguments given
  after ``link`` and passes its table through (the place to add link families to this
  campaign's table is :data:`FAMILIES`).

Each killed run is then recovered (:func:`tsa_bench.store.recover.recover_run`, what
``tsa-bench info`` and ``run --resume`` do) and compared with what its journal held before
(tests/store/kill_checks.py). Prints per family: kills, recoverable (the run reads and holds
every sample, segment and event the journal held and every sample the file held), run files
readable as they were left, runs rebuilt into a new file, and samples recovered vs samples
the journal held. Exit 0 when every kill was recoverable.

    PYTHONPATH=host nice -n 10 python3 scripts/fault_campaign.py all [--every 10] [--phase-kills 60]
"""

from __future__ import annotations

import argparse
import collections
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "host"))

from tests.store.kill_checks import (  # noqa: E402
    STRACE, Outcome, check_recovered, kill_at_write, write_phases,
)

ENV = {**os.environ, "PYTHONPATH": f"{ROOT / 'host'}{os.pathsep}{ROOT}"}
PROTOCOL = ROOT / "configs/protocols/quasi-static-self-sensing.yaml"
DRIVER = [sys.executable, "-m", "tests.store.kill_driver"]
APPEND_PHASES = ("H5Dwrite", "H5Dset_extent")


@dataclass
class Family:
    name: str
    outcomes: list[tuple[str, Outcome]] = field(default_factory=list)
    seconds: float = 0.0

    def add(self, label: str, outcome: Outcome, verbose: bool) -> None:
        self.outcomes.append((label, outcome))
        if verbose or not outcome.recoverable:
            mark = "ok " if outcome.recoverable else "BAD"
            print(f"  {mark} {self.name:<12} {label:<28} held {outcome.held:>7}  "
                  f"{'as is' if outcome.readable_as_is else ('rebuilt' if outcome.rebuilt else 'repaired')}: "
                  f"{outcome.detail[:110]}", flush=True)


def _run_cmd(out: Path) -> list[str]:
    return [sys.executable, "-m", "tsa_bench.cli", "run", str(PROTOCOL), "--speed", "400", "--seed", "3",
            "--output", str(out)]


def kill_writes(args: argparse.Namespace, work: Path) -> list[Family]:
    """(a) every ``--every``-th pwrite64 of a whole run."""
    fam = Family(f"(a) every {args.every}th write of a run")
    t0 = time.monotonic()
    phases = write_phases(_run_cmd(work / "whole.h5"), work / "whole.log", env=ENV, cwd=work)
    print(f"(a) the run makes {len(phases)} pwrite64 calls: {dict(collections.Counter(phases))}", flush=True)
    for n in range(args.every, len(phases) + 1, args.every):
        out = work / f"run-w{n}.h5"
        kill_at_write(_run_cmd(out), n, env=ENV, cwd=work, timeout=600)
        fam.add(f"write {n} ({phases[n - 1]})", check_recovered(out), args.verbose)
    fam.seconds = time.monotonic() - t0
    return [fam]


def kill_phases(args: argparse.Namespace, work: Path) -> list[Family]:
    """(b) kills inside flushes and appends of the driver's run."""
    t0 = time.monotonic()
    phases = write_phases(DRIVER + [str(work / "driver.h5")], work / "driver.log", env=ENV, cwd=ROOT)
    inside = [i + 1 for i, p in enumerate(phases) if p == "H5Fflush" or p in APPEND_PHASES]
    print(f"(b) the driver makes {len(phases)} pwrite64 calls: {dict(collections.Counter(phases))}", flush=True)
    n_writes = max(1, args.phase_kills * 6 // 10)
    step = max(1, len(inside) // n_writes)
    in_writes = Family("(b) writes inside H5Fflush / appends")
    for n in inside[::step][:n_writes]:
        out = work / f"drv-w{n}.h5"
        kill_at_write(DRIVER + [str(out)], n, env=ENV, cwd=ROOT, timeout=300)
        in_writes.add(f"write {n} ({phases[n - 1]})", check_recovered(out), args.verbose)
    hooks = Family("(b) entering appends / flushes")
    rest = args.phase_kills - len(in_writes.outcomes)
    appends = [round(1 + i * (243 / max(1, rest * 2 // 3 - 1))) for i in range(rest * 2 // 3)]
    flushes = [round(1 + i * (54 / max(1, rest - len(appends) - 1))) for i in range(rest - len(appends))]
    for where, points in (("append", appends), ("flush", flushes)):
        for k in points:
            out = work / f"drv-{where}{k}.h5"
            subprocess.run(DRIVER + [str(out), f"--kill-at-{where}", str(k)], env=ENV, cwd=ROOT,
                           capture_output=True, timeout=300)
            hooks.add(f"{where} {k}", check_recovered(out), args.verbose)
    in_writes.seconds = hooks.seconds = (time.monotonic() - t0) / 2
    return [in_writes, hooks]


def link(args: argparse.Namespace, work: Path) -> list[Family]:
    """The link trials: scripts/link_campaign.py with the arguments after ``link``."""
    code = subprocess.run([sys.executable, str(ROOT / "scripts/link_campaign.py"), *args.rest], env=ENV,
                          cwd=ROOT).returncode
    if code:
        raise SystemExit(code)
    return []


#: Trial families by subcommand: each returns the rows of the table. Link families (relay
#: swap, loaded machine) join here as functions returning Family rows.
FAMILIES: dict[str, Callable[[argparse.Namespace, Path], list[Family]]] = {
    "kill-writes": kill_writes, "kill-phases": kill_phases, "link": link,
}


def table(families: list[Family]) -> bool:
    head = f"{'family':<40} {'kills':>5} {'recoverable':>13} {'as is':>6} {'rebuilt':>7} {'samples recovered / held':>26}"
    print("\n" + head + "\n" + "-" * len(head))
    every = True
    for f in families:
        n = len(f.outcomes)
        ok = sum(o.recoverable for _, o in f.outcomes)
        as_is = sum(o.readable_as_is for _, o in f.outcomes)
        rebuilt = sum(o.rebuilt for _, o in f.outcomes)
        held = sum(o.held for _, o in f.outcomes)
        got = sum(o.recovered for _, o in f.outcomes)
        pct = 100.0 * ok / n if n else float("nan")
        print(f"{f.name:<40} {n:>5} {ok:>6} ({pct:5.1f} %) {as_is:>6} {rebuilt:>7} {got:>12,} / {held:<12,}")
        every = every and ok == n
    return every


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("family", choices=[*FAMILIES, "all"])
    ap.add_argument("--every", type=int, default=10, help="(a) kill at every N-th write (default 10)")
    ap.add_argument("--phase-kills", type=int, default=60, help="(b) kills inside flushes and appends (default 60)")
    ap.add_argument("--keep", type=Path, default=None, help="keep the killed runs in this folder")
    ap.add_argument("--verbose", action="store_true", help="one line per kill")
    args, rest = ap.parse_known_args()   # (link) the other arguments go to scripts/link_campaign.py
    if rest and args.family != "link":
        ap.error(f"unrecognized arguments: {' '.join(rest)}")
    args.rest = rest
    if args.family != "link" and STRACE is None:
        raise SystemExit("strace is needed (apt-get install strace; scripts/setup-firmware-toolchain.sh)")
    names = ["kill-writes", "kill-phases"] if args.family == "all" else [args.family]
    with tempfile.TemporaryDirectory(prefix="fault-campaign-") as tmp:
        work = args.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        families = [row for name in names for row in FAMILIES[name](args, work)]
    if families:
        sys.exit(0 if table(families) else 1)


if __name__ == "__main__":
    main()
