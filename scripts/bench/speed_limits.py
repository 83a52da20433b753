#!/usr/bin/env python3
"""Every speed and memory figure of the bench side by side with the floor it is measured against.

Whole-process figures (a fresh ``python`` per measurement, min / median of ``--repeat``
runs, peak RSS of the child from ``wait4``), printed as one table:

* ``run lifetime.yaml`` on the simulated bench: wall s and real-time factor, against the
  plant alone (the same number of ``plant.sample`` calls in a fresh process: the floor
  of any simulated run);
* ``--help`` and ``info`` against ``import click``;
* ``run`` peak RSS at lifetime and 10x lifetime (``--long``; the 10x protocol is the
  lifetime protocol with 10x the cycles), against flat (the lifetime figure);
* run file size in bytes per sample, against the sample columns' own compressed size;
* ``diagnose`` at 1x (and 10x with ``--long``): wall s, CPU s and peak RSS (with
  ``--baseline``, the other checkout's diagnose on the same file right after each);
* every model ``tsa-bench fit`` offers (``tsa_bench.models.fitting.fit``, quasi-static
  mask included; ``--fits`` picks some) at 1x / 4x / 10x lifetime (the lifetime run tiled
  in time): whole-process s and peak RSS and the fit's own CPU s, against linear (the 1x
  figure times the factor);
* the SAMPLE frame and a full SAMPLE_BLOCK: bytes on the wire per sample and samples/s the 250 kbaud line
  carries, against the ADS1115's 860 samples/s.

    python3 scripts/bench/speed_limits.py [--repeat 3] [--long] [--keep DIR] [--baseline CHECKOUT]
                                          [--skip-diagnose] [--skip-fit]

``--baseline`` measures another checkout's ``run lifetime.yaml`` alternately with this
one (``git worktree add /tmp/base main``), so a speed-up is read side by side.

Run it on a quiet machine: figures are wall time of whole processes.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LIFETIME = ROOT / "configs" / "protocols" / "lifetime.yaml"
CLI = [sys.executable, "-m", "tsa_bench.cli"]
LINE_BAUD = 250_000
ADS1115_SPS = 860

PLANT_LOOP = """
import sys, time
from tsa_bench.bench import load_bench
from tsa_bench.sim.plant import plant_from_config
n = int(sys.argv[1])
plant = plant_from_config(load_bench(None).plant, seed=1)
plant.set_load(550.0)
for i in range(n):
    plant.sample(i * 0.1, 15 + (i // 17) % 10, 0.0, i % 17 < 7)
"""

FIT_CHILD = """
import sys, time, numpy as np
from tsa_bench.store import read_run
from tsa_bench.rundata import RunData
from tsa_bench.models.fitting import fit
run = read_run(sys.argv[1]); k = int(sys.argv[2])
t = run.samples["t"]; span = float(t[-1] - t[0]) + float(t[1] - t[0])
cols = {}
for name, col in run.samples.items():
    if name == "t":
        cols[name] = np.concatenate([col + i * span for i in range(k)])
    elif name == "segment":
        n_seg = int(col.max()) + 1
        cols[name] = np.concatenate([col + i * n_seg for i in range(k)])
    else:
        cols[name] = np.tile(col, k)
tiled = RunData(run.path, run.attrs, cols, run.units, None, None)
io = ("turns", "length") if sys.argv[3] in ("preisach", "polynomial") else (None, None)
c0 = time.process_time()
fit(sys.argv[3], [tiled], *io)
print(time.process_time() - c0)
"""
#: models `tsa-bench fit` offers (cli/models.py); the strain-resistance and self-sensing models
#: are identified on whole hold curves, which a lifetime run has only at its 1 s pauses
FIT_MODELS = ("preisach", "polynomial", "strain-resistance", "self-sensing")


def env(root: Path = ROOT) -> dict[str, str]:
    e = dict(os.environ)
    e["PYTHONPATH"] = str(root / "host")
    return e


LAST_CPU: list[float] = [0.0]
LAST_OUT: list[float | None] = [None]


def rss_of(argv: list[str], root: Path = ROOT, timeout: float | None = None) -> tuple[float, float]:
    """(wall s, peak RSS MiB) measured in a fresh wrapper process, so ru_maxrss is this
    child's alone; its CPU seconds (user + system) go to ``LAST_CPU[0]`` and the last line
    the child printed to ``LAST_OUT[0]`` (a float, or None)."""
    wrapper = ("import resource, subprocess, sys, time; t=time.perf_counter(); lim=float(sys.argv[1]) or None\n"
               "try: r=subprocess.run(sys.argv[2:], stdout=subprocess.PIPE, text=True, timeout=lim)\n"
               "except subprocess.TimeoutExpired: sys.exit(3)\n"
               "w=time.perf_counter()-t; u=resource.getrusage(resource.RUSAGE_CHILDREN); "
               "last=(r.stdout.strip().splitlines() or ['nan'])[-1].split()[-1]; "
               "print(w, u.ru_maxrss/1024.0, u.ru_utime+u.ru_stime, last); sys.exit(r.returncode)")
    proc = subprocess.run([sys.executable, "-c", wrapper, str(timeout or 0), *argv], capture_output=True,
                          env=env(root), text=True, cwd=root)
    if proc.returncode == 3 and timeout:
        raise subprocess.TimeoutExpired(argv, timeout)
    if proc.returncode != 0:
        sys.exit(f"speed_limits: {' '.join(argv[:6])} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    wall, rss, cpu, last = proc.stdout.split()[-4:]
    LAST_CPU[0] = float(cpu)
    try:
        LAST_OUT[0] = float(last)
    except ValueError:
        LAST_OUT[0] = None
    return float(wall), float(rss)


def repeated(argv: list[str], n: int) -> tuple[list[float], list[float]]:
    walls, rss = [], []
    for _ in range(n):
        w, r = rss_of(argv)
        walls.append(w)
        rss.append(r)
    return walls, rss


def mm(values: list[float], fmt: str = ".2f") -> str:
    return f"{min(values):{fmt}} / {statistics.median(values):{fmt}}"


def row(figure: str, now: str, floor: str) -> None:
    print(f"| {figure} | {now} | {floor} |")
    sys.stdout.flush()


def run_file(protocol: Path, out: Path) -> list[str]:
    return [*CLI, "run", str(protocol), "--output", str(out), "--seed", "1"]


def scaled_protocol(factor: int, where: Path) -> Path:
    text = LIFETIME.read_text()
    assert "count: 596" in text
    path = where / f"lifetime-x{factor}.yaml"
    path.write_text(text.replace("name: lifetime", f"name: lifetime-x{factor}")
                    .replace("count: 596", f"count: {596 * factor}"))
    return path


def file_figures(path: Path) -> tuple[int, float, float, float, float]:
    """(samples, device s, file bytes per sample, sample-column bytes per sample, segment-table
    bytes per sample: /segments with its /segment_texts, texts' heap included)."""
    import h5py
    with h5py.File(path, "r") as f:
        n = len(f["samples/t"])
        cols = sum(d.id.get_storage_size() for d in f["samples"].values())
        device_s = float(f.attrs["duration_s"])
        seg = 0
        for name in ("segments", "segment_texts"):
            if name not in f:
                continue
            ds = f[name]
            seg += ds.id.get_storage_size()
            texts = [k for k in ds.dtype.names or () if ds.dtype[k].kind == "O"]   # variable-length: their heap
            data = ds[()]
            if ds.dtype.kind == "O":
                seg += sum(len(v) for v in data)
            for k in texts:
                seg += sum(len(v) for v in data[k])
    return n, device_s, path.stat().st_size / n, cols / n, seg / n


def frame_figures() -> tuple[int, int, float]:
    """(SAMPLE payload bytes, frame bytes, samples/s the line carries)."""
    sys.path.insert(0, str(ROOT / "host"))
    from tsa_bench.protocol import encode, msg
    frame = encode(msg.Sample(123456, 12_345_678_901, -12345, -1234, 123456, 0, 0, 1, 1234), 0xFFFE)
    payload = msg.MESSAGES[0x83].struct.size
    return payload, len(frame), LINE_BAUD / 10 / len(frame)


def block_figures() -> tuple[int, float]:
    """(samples per full SAMPLE_BLOCK, wire bytes per sample in it)."""
    from tsa_bench.protocol.blocks import FULL_BLOCK_BYTES, SAMPLES_PER_BLOCK
    return SAMPLES_PER_BLOCK, FULL_BLOCK_BYTES / SAMPLES_PER_BLOCK


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="whole-process runs per figure (min / median shown)")
    ap.add_argument("--long", action="store_true", help="also the 10x lifetime figures (run RSS, diagnose): minutes")
    ap.add_argument("--keep", type=Path, default=None, help="keep the run files here")
    ap.add_argument("--skip-diagnose", action="store_true")
    ap.add_argument("--fits", default=",".join(FIT_MODELS),
                    help=f"models fitted at 1x / 4x / 10x, comma-separated (default: {','.join(FIT_MODELS)}; "
                         "'none' skips them)")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds before one fit is given up (printed)")
    ap.add_argument("--skip-fit", action="store_true", help="leave out the fit figures (same as --fits none)")
    ap.add_argument("--baseline", type=Path, default=None,
                    help="another checkout (e.g. `git worktree add /tmp/base main`): its `run lifetime.yaml` "
                         "is measured too, alternating with this one, for a side-by-side speed-up")
    args = ap.parse_args()
    n = max(1, args.repeat)
    tmp = Path(args.keep or tempfile.mkdtemp(prefix="speed-limits-"))
    tmp.mkdir(parents=True, exist_ok=True)
    print(f"speed_limits: {n} whole-process runs per figure (min / median), {os.cpu_count()} cores, files in {tmp}")
    print("| figure | now | floor or limit |")
    print("|---|---|---|")

    # run lifetime vs the plant alone (and vs a baseline checkout, alternating)
    walls, rss, cpus, base_walls, base_cpus = [], [], [], [], []
    for i in range(n):
        out = tmp / f"lifetime-{i}.h5"
        out.unlink(missing_ok=True)
        w, r = rss_of(run_file(LIFETIME, out))
        walls.append(w)
        rss.append(r)
        cpus.append(LAST_CPU[0])
        if args.baseline is not None:
            out = tmp / f"baseline-{i}.h5"
            out.unlink(missing_ok=True)
            bw, _ = rss_of(run_file(args.baseline / "configs" / "protocols" / "lifetime.yaml", out), args.baseline)
            base_walls.append(bw)
            base_cpus.append(LAST_CPU[0])
    samples, device_s, bps, col_bps, seg_bps = file_figures(tmp / "lifetime-0.h5")
    pw, _ = repeated([sys.executable, "-c", PLANT_LOOP, str(samples)], n)
    pcpu = LAST_CPU[0]
    row(f"`run lifetime.yaml` ({device_s / 3600:.2f} h device time, {samples:,} samples), s",
        f"{mm(walls)} -> {device_s / min(walls):,.0f}x / {device_s / statistics.median(walls):,.0f}x real time "
        f"(CPU {mm(cpus)} s)",
        f"plant alone {mm(pw)} -> {device_s / min(pw):,.0f}x / {device_s / statistics.median(pw):,.0f}x "
        f"(CPU {pcpu:.2f} s)")
    if base_walls:
        row(f"  same, baseline {args.baseline}", f"{mm(base_walls)} -> {device_s / min(base_walls):,.0f}x / "
            f"{device_s / statistics.median(base_walls):,.0f}x (CPU {mm(base_cpus)} s)",
            f"speed-up {min(base_walls) / min(walls):.2f}x (min), "
            f"{statistics.median(base_walls) / statistics.median(walls):.2f}x (median), "
            f"CPU {min(base_cpus) / min(cpus):.2f}x")

    hw, _ = repeated([*CLI, "--help"], n)
    iw, _ = repeated([*CLI, "info", str(tmp / "lifetime-0.h5")], n)
    cw, _ = repeated([sys.executable, "-c", "import click"], n)
    row("`tsa-bench --help` / `info RUN.h5`, s", f"{mm(hw)} / {mm(iw)}", f"`import click` {mm(cw)}")

    rss10 = ""
    if args.long:
        p10 = scaled_protocol(10, tmp)
        out10 = tmp / "lifetime-x10.h5"
        out10.unlink(missing_ok=True)
        w10, r10 = rss_of(run_file(p10, out10))
        n10, d10, bps10, _, _ = file_figures(out10)
        rss10 = f" / 10x {r10:.0f} MiB ({(r10 / min(rss) - 1) * 100:+.0f} %; 10x run {w10:.1f} s, " \
                f"{d10 / w10:,.0f}x real time)"
    row("`run` peak RSS lifetime" + (" / 10x lifetime" if args.long else "") + ", MiB",
        f"{mm(rss, '.0f')}{rss10}", "flat (10x within 10 % of 1x)")
    row("run file size, B/sample", f"{bps:.1f} (of which /segments and its texts {seg_bps:.1f})"
        + (f"; 10x lifetime {bps10:.1f}" if args.long else ""),
        f"sample columns alone (shuffle+gzip) {col_bps:.1f}; target <= 15")

    if not args.skip_diagnose:
        files = [("1x", tmp / "lifetime-0.h5")] + ([("10x", tmp / "lifetime-x10.h5")] if args.long else [])
        for label, path in files:
            argv = ["diagnose", "-q", "--out", str(tmp / f"diag-{label}"), str(path)]
            dw, dr = rss_of([*CLI, *argv])
            text = f"{dw:.1f} s, CPU {LAST_CPU[0]:.1f} s, {dr:.0f} MiB"
            if args.baseline is not None:
                bw, br = rss_of([*CLI, *argv[:3], str(tmp / f"diag-base-{label}"), str(path)], args.baseline)
                text += f" | baseline {bw:.1f} s, CPU {LAST_CPU[0]:.1f} s, {br:.0f} MiB"
            row(f"`diagnose` {label} lifetime (wall, CPU, peak RSS)", text,
                "10x: <= 30 s, <= 500 MiB" if label == "10x" else "-")

    for model in [] if args.skip_fit else [m for m in args.fits.split(",") if m and m != "none"]:
        fits = []
        for k in (1, 4, 10):
            try:
                w, r = rss_of([sys.executable, "-c", FIT_CHILD, str(tmp / "lifetime-0.h5"), str(k), model],
                              timeout=args.timeout)
            except subprocess.TimeoutExpired:
                fits.append((k, None, None, None))
                break
            fits.append((k, w, r, LAST_OUT[0]))
        base = fits[0][3]
        row(f"`fit {model}` (read, tile, mask, fit) at 1x / 4x / 10x lifetime: wall s, peak MiB, fit CPU s",
            " / ".join(f"{k}x {w:.1f} s {r:.0f} MiB (fit {c:.2f} s)" if w is not None else
                       f"{k}x over {args.timeout:.0f} s" for k, w, r, c in fits),
            "linear: " + (" / ".join(f"{base * k:.2f} s" for k, *_ in fits) if base is not None else "-"))

    payload, frame, sps = frame_figures()
    row("SAMPLE frame", f"{frame} B for a {payload} B payload ({(frame - payload) / payload * 100:.1f} % overhead on the payload): "
        f"{sps:.0f} samples/s at {LINE_BAUD // 1000} kbaud", f"ADS1115 {ADS1115_SPS} samples/s")
    per_block, block_b = block_figures()
    row("SAMPLE_BLOCK frame", f"{block_b:.1f} B per sample in a full block of {per_block}: "
        f"{LINE_BAUD / 10 / block_b:.0f} samples/s at {LINE_BAUD // 1000} kbaud (simavr figures: "
        "scripts/bench/wire_limit.py)", f"ADS1115 {ADS1115_SPS} samples/s")


if __name__ == "__main__":
    main()
