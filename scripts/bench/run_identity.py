#!/usr/bin/env python3
"""Are the recorded runs of this checkout identical to another checkout's?

Runs each shipped protocol (``--protocols``; default the five below, closed-loop ones
included) with ``--seed 1`` on the simulated bench its metadata names (else sim.yaml)
in this checkout and in ``--baseline``, then compares the files dataset by dataset:
every sample column, ``/segments``, ``/segment_texts`` and ``/events`` must be equal
element for element (NaN equal to NaN). Attributes (timestamps, wall times, paths) are
not compared. Prints one line per protocol and exits 1 when any file differs.

    python3 scripts/bench/run_identity.py --baseline /path/to/other/checkout [--keep DIR]

A speed-up of the run loop must leave every line "identical".
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
PROTOCOLS = ["lifetime", "transient-steps", "quasi-static-self-sensing", "quasi-static-self-sensing-settled",
             "track-length-steps", "twist-heat-grid"]


def bench_of(protocol: Path) -> str | None:
    found = re.search(r"bench:\s*([\w.-]+)\s*}", protocol.read_text())
    return found.group(1) if found else None


def run(checkout: Path, name: str, out: Path) -> None:
    protocol = checkout / "configs" / "protocols" / f"{name}.yaml"
    argv = [sys.executable, "-m", "tsa_bench.cli", "run", str(protocol), "--output", str(out), "--seed", "1"]
    bench = bench_of(protocol)
    if bench:
        argv += ["--bench", str(checkout / "configs" / "bench" / f"{bench}.yaml")]
    env = {**os.environ, "PYTHONPATH": str(checkout / "host")}
    done = subprocess.run(argv, env=env, cwd=checkout, capture_output=True, text=True, timeout=900)
    if done.returncode != 0:
        raise SystemExit(f"{checkout}: run {name} failed ({done.returncode}): {done.stderr.strip()[-500:]}")


def datasets(path: Path, checkout: Path = ROOT) -> dict[str, np.ndarray]:
    """The compared datasets; the checkout's own path in segment texts (a model's path) is
    replaced by a placeholder."""
    out: dict[str, np.ndarray] = {}
    root = str(checkout.resolve()).encode()
    with h5py.File(path, "r") as f:
        for name in ("segments", "segment_texts", "events"):
            if name in f:
                out[name] = f[name][()]
        if "segment_texts" in out:
            out["segment_texts"] = np.array([t.replace(root, b"<checkout>") if isinstance(t, bytes) else t
                                             for t in out["segment_texts"]], dtype=object)
        for name, ds in f["samples"].items():
            out[f"samples/{name}"] = ds[()]
    return out


def equal(a: np.ndarray, b: np.ndarray) -> bool:
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    if a.dtype.names:
        return all(equal(a[n], b[n]) for n in a.dtype.names)
    if a.dtype.kind == "f":
        return bool(np.array_equal(a, b, equal_nan=True))
    return bool(np.array_equal(a, b))


def differences(mine: Path, theirs: Path, baseline: Path) -> list[str]:
    a, b = datasets(mine), datasets(theirs, baseline)
    out = [f"{k}: only in one file" for k in sorted(set(a) ^ set(b))]
    out += [f"{k}: differs ({a[k].shape} vs {b[k].shape})" for k in sorted(set(a) & set(b)) if not equal(a[k], b[k])]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", type=Path, required=True, help="the other checkout")
    ap.add_argument("--protocols", nargs="*", default=PROTOCOLS, help="protocol names under configs/protocols")
    ap.add_argument("--keep", type=Path, help="keep the run files here")
    ap.add_argument("--reuse-baseline", action="store_true",
                    help="with --keep: use the baseline files already there instead of running them again")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = args.keep or Path(tmp_name)
        tmp.mkdir(parents=True, exist_ok=True)
        bad = 0
        for name in args.protocols:
            mine, theirs = tmp / f"{name}-this.h5", tmp / f"{name}-baseline.h5"
            mine.unlink(missing_ok=True)
            run(ROOT, name, mine)
            if not (args.reuse_baseline and theirs.exists()):
                run(args.baseline.resolve(), name, theirs)
            diff = differences(mine, theirs, args.baseline)
            n = len(datasets(mine).get("samples/t", []))
            print(f"{name}: {n:,} samples: " + ("identical" if not diff else "DIFFERENT: " + "; ".join(diff)),
                  flush=True)
            bad += bool(diff)
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
