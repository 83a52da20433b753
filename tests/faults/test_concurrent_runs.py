"""Runs started together into one folder take different names (the name is reserved by an
exclusive create, not checked with exists() first): six runs, six files, six successes,
with HDF5's file locking on or off (off is usual on network file systems)."""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tsa_bench import catalogue
from tsa_bench.outputs import reserve_free_name
from tsa_bench.store import read_run

ROOT = Path(__file__).resolve().parents[2]
PROTOCOL = ROOT / "configs/protocols/stiffness-3ply.yaml"


def _reserve(folder: str, barrier, names) -> None:
    barrier.wait()
    names.append(reserve_free_name(folder, "20260101-000000_same").name)


def test_six_processes_asking_for_one_name_at_once_get_six_names(tmp_path):
    ctx = multiprocessing.get_context("fork")
    barrier, names = ctx.Barrier(6), ctx.Manager().list()
    procs = [ctx.Process(target=_reserve, args=(str(tmp_path), barrier, names)) for _ in range(6)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    assert [p.exitcode for p in procs] == [0] * 6
    assert sorted(names) == sorted(["20260101-000000_same.h5"] + [f"20260101-000000_same-{n}.h5" for n in range(2, 7)])


@pytest.mark.parametrize("locking", ["TRUE", "FALSE"])
def test_six_runs_started_together_into_one_folder(tmp_path, locking):
    out = tmp_path / "runs"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "host"), "HDF5_USE_FILE_LOCKING": locking}
    env.pop(catalogue.ENV_VAR, None)   # the default catalogue: the SQLite file beside the runs
    procs = [subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", "run", str(PROTOCOL), "--out", str(out),
                               "--seed", str(i)], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for i in range(6)]
    results = [p.communicate(timeout=600) for p in procs]
    assert [p.returncode for p in procs] == [0] * 6, [r[1][-400:] for r in results]
    files = sorted(out.glob("*.h5"))
    # nothing else left but the folder's catalogue, which lists each run once
    assert len(files) == 6
    assert sorted(os.listdir(out)) == sorted([f.name for f in files] + [catalogue.CATALOGUE_FILE])
    with catalogue.open(out) as cat:
        rows = cat.search()
    assert sorted(Path(r.path).name for r in rows) == [f.name for f in files]
    assert {r.status for r in rows} == {"success"}
    wrote = sorted(line.split()[1] for stdout, _ in results for line in stdout.splitlines()
                   if line.startswith("wrote "))
    assert wrote == sorted(str(f) for f in files)   # each names its own file
    seeds = set()
    for f in files:
        run = read_run(f)
        assert run.exit_status == "success" and len(run) > 1000
        seeds.add(run.samples["resistance"].tobytes())
    assert len(seeds) == 6   # six different runs (seeds 0..5), none overwritten by another
