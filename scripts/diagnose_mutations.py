#!/usr/bin/env python3
"""Remove each safeguard of `tsa-bench diagnose` in turn and show which tests then fail.

Each mutation is applied to a TEMPORARY COPY of the package (host/tsa_bench copied into a
fresh folder, beside links to the checkout's configs/, firmware/ and protocol/; the checkout
is never changed); the analysis tests are run against that copy
(PYTHONPATH puts it first) and the failing tests listed. A mutation that no test catches
is reported as SURVIVED and the script exits 1; a mutation whose pattern is no longer in
the source (the code moved on) exits 2, so the script cannot pass by missing its target.

    python3 scripts/diagnose_mutations.py            # every mutation, the analysis tests (safeguards first)
    python3 scripts/diagnose_mutations.py --fast     # stop each run at its first failure
    python3 scripts/diagnose_mutations.py --only gate-removed --tests tests/analysis/test_diagnose_safeguards.py

The mutations (what the issue lists):

* ``top-screened-named``: the top-screened candidate is named without the gate;
* ``gate-removed``: the naming gate passes everything;
* ``calibration-on-held-out``: the calibration subsample's training mask covers the held-out samples;
* ``demoted-kept``: a cause demoted by backward elimination stays in the final model;
* ``soft-bound-ignored``: a form parameter at the edge of its range no longer caps the confidence;
* ``bootstrap-point``: the block bootstrap's replicates are the sample itself (a point estimate).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "host" / "tsa_bench"
#: the analysis tests, the safeguards' own first (with --fast a run stops at its first failure)
TESTS = ["tests/analysis/test_diagnose_safeguards.py", "tests/analysis/test_diagnose_second.py", "tests/analysis"]

#: name -> (file under host/tsa_bench, exact text, replacement)
MUTATIONS: dict[str, tuple[str, str, str]] = {
    "top-screened-named": (
        "analysis/naming.py",
        '    passing = [f for f, r in results.items() if r["ok"]]\n',
        '    passing = list(results)[:1]   # MUTATION: the top-screened form, gate or not\n'
        '    for f in passing:\n        results[f]["ok"] = True\n'),
    "gate-removed": (
        "analysis/naming.py",
        '    if not c.significant(0.0):\n        return False, "held-out improvement not significant',
        '    return True, "passes"   # MUTATION: no gate\n'
        '    if not c.significant(0.0):\n        return False, "held-out improvement not significant'),
    "calibration-on-held-out": (
        "analysis/context.py",
        "return Problem(self.inputs, idx, [~r.heldout[i] for r, i in zip(self.inputs, idx)],",
        "return Problem(self.inputs, idx, [np.ones(len(i), bool) for r, i in zip(self.inputs, idx)],"),
    "demoted-kept": (
        "analysis/search.py",
        "    kept = [c for c in chosen if c is not w]\n",
        "    kept = [c for c in chosen if c is not w]\n"
        "    return current, scores, kept, demoted   # MUTATION: the demoted cause stays in the model\n"),
    "soft-bound-ignored": (
        "analysis/confusion.py",
        "    for b in at_bound:\n",
        "    for b in []:   # MUTATION: a parameter at a soft bound is ignored\n"),
    "bootstrap-point": (
        "analysis/scoring.py",
        "    pick = rng.integers(0, m, size=(n_boot, m))\n    dsum",
        "    pick = np.tile(np.arange(m), (n_boot, 1))   # MUTATION: no resampling\n    dsum"),
}


def mutate(copy: Path, name: str) -> None:
    rel, old, new = MUTATIONS[name]
    path = copy / "host" / "tsa_bench" / rel
    text = path.read_text()
    if text.count(old) != 1:
        raise SystemExit(f"mutation {name}: its target is not (exactly once) in host/tsa_bench/{rel}; update the script")
    path.write_text(text.replace(old, new))


def failing_tests(copy: Path, tests: list[str], fast: bool) -> tuple[list[str], int, str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(copy / "host"), str(ROOT)]),
           "PYTHONDONTWRITEBYTECODE": "1"}
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-rfE", *(["-x"] if fast else []), *tests]
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    failed = sorted(set(re.findall(r"^(?:FAILED|ERROR) (\S+)", proc.stdout, re.M)))
    tail = proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else proc.stderr.strip()[-200:]
    return failed, proc.returncode, tail


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", action="append", choices=sorted(MUTATIONS), help="run this mutation only (repeatable)")
    ap.add_argument("--tests", nargs="+", default=TESTS, help="test paths (default: tests/analysis, the safeguard and "
                    "second-generator tests first)")
    ap.add_argument("--fast", action="store_true", help="stop each test run at its first failure")
    args = ap.parse_args()
    names = args.only or list(MUTATIONS)
    rows, survived = [], []
    with tempfile.TemporaryDirectory(prefix="diagnose-mutants-") as tmp:
        for name in names:
            copy = Path(tmp) / name       # <copy>/host/tsa_bench beside links to the checkout's other folders
            shutil.copytree(PACKAGE, copy / "host" / "tsa_bench", ignore=shutil.ignore_patterns("__pycache__"))
            for other in ("configs", "firmware", "protocol"):
                if (ROOT / other).exists():
                    (copy / other).symlink_to(ROOT / other)
            mutate(copy, name)
            print(f"mutation {name}: running {' '.join(args.tests)} ...", file=sys.stderr, flush=True)
            failed, code, tail = failing_tests(copy, args.tests, args.fast)
            if not failed:
                survived.append(name)
            rows.append((name, failed, tail))
    print(f"{'mutation':<26} failing tests")
    for name, failed, tail in rows:
        print(f"{name:<26} {len(failed)} failed" + ("  SURVIVED" if not failed else f" ({tail})"))
        for t in failed:
            print(f"{'':<26}   {t}")
    return 1 if survived else 0


if __name__ == "__main__":
    sys.exit(main())
