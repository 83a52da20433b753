#!/usr/bin/env python3
"""The run catalogue's speed: a search among 10,000 runs, and a rebuild from 1,000 run files.

1. ``ls --where`` on ``--rows`` (10,000) registered runs (synthetic rows: 40 samples, 4
   loads, 4 statuses, a year of start dates, metadata), in a SQLite catalogue and, when
   ``--postgres URL`` is given (or the test server of scripts/setup-test-services.sh
   answers), in a PostgreSQL database made for it and dropped after. Figures, median of
   ``--repeat``: the search itself (``Catalogue.search`` of ``sample=S3``,
   ``load_g>=200``, ``--status success``, ``--since``), the whole ``ls`` command in this
   process (search, each listed file's state, the table), and ``tsa-bench ls`` as a new
   process (interpreter start-up included). Target: 0.2 s.
2. ``tsa-bench catalogue rebuild`` of ``--files`` (1,000) run files: copies of the run
   files in ``--source`` (default: the four lifetime runs of configs/labs/four-sim-rigs.yaml,
   recorded first), each copy made distinct (its metadata and start time changed, so every
   file has its own hash). Figure: the command's wall time (every file read in a bounded
   child and hashed). Target: 30 s.

    nice -n 10 python3 scripts/bench/catalogue_speed.py [--rows 10000] [--files 1000]
                                                        [--source DIR] [--postgres URL]
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import random
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "host")}
CLI = [sys.executable, "-m", "tsa_bench.cli"]
WHERE = ["--where", "sample=S3", "--where", "load_g>=200", "--status", "success", "--since", "2026-06-01"]
TEST_PG = "postgresql:///tsa_bench_test?host=/var/run/postgresql"


def fill(url: str, folder: Path, n: int) -> None:
    """``n`` synthetic rows for run files in ``folder``, in one transaction."""
    from sqlalchemy import insert

    from tsa_bench import catalogue
    from tsa_bench.catalogue.database import now_utc
    from tsa_bench.catalogue.schema import runs

    rng = random.Random(1)
    start = dt.datetime(2026, 1, 1)
    rows = []
    for i in range(n):
        sample = f"S{rng.randrange(40)}"
        load = rng.choice([100.0, 200.0, 350.0, 550.0])
        rows.append(dict(host=os.uname().nodename, path=str(folder / f"run-{i:05d}.h5"), kind="recorded",
                         status=rng.choice(["success", "success", "aborted", "failed"]), reason="", plan="lifetime",
                         bench="sim", backend="sim", port="sim://", rig=rng.choice("ABCD"), sample=sample,
                         load_g=load, operator="ana", started=start + dt.timedelta(minutes=50 * i),
                         ended=start + dt.timedelta(minutes=50 * i + 30), device_time_s=10_096.0, samples=100_956,
                         samples_lost=0, segments_done=11_928, n_segments=11_928, sha256=uuid.uuid4().hex * 2,
                         size_bytes=1_000_000, mtime_ns=0, meta={"sample": sample, "load_g": load, "batch": f"B{i % 7}"},
                         updated=now_utc()))
    with catalogue.open(url) as cat:
        with cat.engine.begin() as conn:
            conn.execute(insert(runs), rows)


def timed(fn, repeat: int) -> tuple[float, object]:
    fn()   # warm: the first call pays the imports and the connection
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def search_figures(name: str, url: str, folder: Path, rows: int, repeat: int) -> None:
    from click.testing import CliRunner

    from tsa_bench import catalogue
    from tsa_bench.cli import main

    fill(url, folder, rows)
    with catalogue.open(url) as cat:
        search_s, found = timed(lambda: cat.search(["sample=S3", "load_g>=200"], status="success",
                                                   since="2026-06-01"), repeat)
    proc_cpu_s()
    runner = CliRunner()
    args = ["ls", str(folder), "--catalogue", url, *WHERE]
    ls_s, res = timed(lambda: runner.invoke(main, args), repeat)
    assert res.exit_code == 0, res.output
    cli_times, cli_cpu = [], []
    for _ in range(repeat):
        t0 = time.perf_counter()
        proc = subprocess.Popen(CLI + args, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        stdout, stderr = proc.communicate()
        cli_times.append(time.perf_counter() - t0)
        cli_cpu.append(proc_cpu_s())
        assert proc.returncode == 0, stderr
    listed = len(stdout.splitlines()) - 1
    print(f"{name:<11} {rows:>7} rows  search {search_s * 1000:7.1f} ms  ls in-process {ls_s * 1000:7.1f} ms  "
          f"ls as a new process {statistics.median(cli_times) * 1000:6.0f} ms wall, "
          f"{statistics.median(cli_cpu) * 1000:4.0f} ms CPU (interpreter start-up and imports included)  "
          f"({len(found)} runs found, {listed} listed; target 200 ms)")


_last_children_cpu = [0.0]


def proc_cpu_s() -> float:
    """CPU s of the children waited for since the last call."""
    import resource

    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    total = ru.ru_utime + ru.ru_stime
    used, _last_children_cpu[0] = total - _last_children_cpu[0], total
    return used


def pg_database(base: str):
    """(URL of a new database, drop function), or None when no server answers."""
    from sqlalchemy import create_engine, text
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import OperationalError, SQLAlchemyError

    from tsa_bench.catalogue.database import _url_of

    admin = create_engine(_url_of(base), isolation_level="AUTOCOMMIT")
    name = f"tsa_speed_{uuid.uuid4().hex[:10]}"
    try:
        with admin.connect() as conn:
            conn.execute(text(f'CREATE DATABASE "{name}"'))
    except (OperationalError, SQLAlchemyError, ImportError) as exc:
        print(f"postgresql: skipped ({str(exc).splitlines()[0]})")
        return None

    def drop() -> None:
        with admin.connect() as conn:
            conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()

    return make_url(admin.url).set(database=name).render_as_string(hide_password=False), drop


def sources(folder: Path, given: Path | None) -> list[Path]:
    if given is not None:
        found = sorted(p for p in given.glob("*.h5") if p.is_file())
        if not found:
            raise SystemExit(f"no run files in {given}")
        return found
    out = folder / "lab"
    done = subprocess.run(CLI + ["lab", str(ROOT / "configs" / "labs" / "four-sim-rigs.yaml"), "--out", str(out),
                                 "--catalogue", "none"], env=ENV, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"the lab failed: {done.stdout[-2000:]}{done.stderr[-2000:]}")
    return sorted(out.glob("*.h5"))


def rebuild_figures(folder: Path, files: int, given: Path | None) -> None:
    import h5py

    runs = folder / "many"
    runs.mkdir()
    src = sources(folder, given)
    for i in range(files):
        copy = runs / f"{i:05d}_{src[i % len(src)].name}"
        shutil.copyfile(src[i % len(src)], copy)
        with h5py.File(copy, "a") as f:
            meta = json.loads(f.attrs.get("metadata", "{}"))
            meta.update(sample=f"S{i % 40}", copy=i)
            f.attrs["metadata"] = json.dumps(meta)
            f.attrs["created"] = (dt.datetime(2026, 1, 1, tzinfo=dt.timezone.utc)
                                  + dt.timedelta(hours=i)).isoformat(timespec="seconds")
    size = sum(p.stat().st_size for p in runs.glob("*.h5"))
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    proc = subprocess.Popen(CLI + ["catalogue", "rebuild", str(runs)], env=ENV, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    _, status, usage = os.wait4(proc.pid, 0)     # CPU of the command and the readers it waited for
    wall = time.perf_counter() - t0
    out, err = proc.stdout.read(), proc.stderr.read()
    assert status == 0, err
    print(f"rebuild     {files:>7} run files ({size / 1e9:.2f} GB, copies of {len(src)} runs of "
          f"{src[0].stat().st_size / 1e6:.1f} MB)  {wall:6.1f} s wall, {usage.ru_utime + usage.ru_stime:.1f} CPU s, "
          f"load average {load:.1f} (target 30 s): {out.strip()}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=10_000)
    ap.add_argument("--files", type=int, default=1_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--source", type=Path, help="run files to copy for the rebuild (default: record the lab's)")
    ap.add_argument("--postgres", default=None, help=f"a PostgreSQL URL to create a database from (default {TEST_PG})")
    ap.add_argument("--skip-rebuild", action="store_true")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}, nice {os.nice(0)}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "sqlite").mkdir()
        search_figures("sqlite", str(folder / "sqlite" / "catalogue.sqlite"), folder / "sqlite", args.rows,
                       args.repeat)
        pg = pg_database(args.postgres or TEST_PG)
        if pg is not None:
            url, drop = pg
            try:
                (folder / "pg").mkdir()
                search_figures("postgresql", url, folder / "pg", args.rows, args.repeat)
            finally:
                drop()
        if not args.skip_rebuild:
            rebuild_figures(folder, args.files, args.source)
    print(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
