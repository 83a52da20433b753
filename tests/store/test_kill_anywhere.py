"""A run killed at any instant - inside the HDF5 library's flush, inside a column append,
while creating or closing its file - is recovered with every sample, segment record and
event its journal held (scripts/fault_campaign.py runs many more of these)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.store.kill_checks import STRACE, check_recovered, count_writes, kill_at_write

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": f"{ROOT / 'host'}{os.pathsep}{ROOT}"}
DRIVER = [sys.executable, "-m", "tests.store.kill_driver"]
#: Column appends and file flushes the driver makes (tests.store.kill_driver, counted once).
APPENDS, FLUSHES = 244, 55


def _assert_all_recovered(results: dict) -> None:
    bad = {k: o.detail for k, o in results.items() if not o.recoverable or o.recovered != o.held}
    assert not bad, bad
    assert sum(o.held for o in results.values()) > 0


@pytest.mark.skipif(STRACE is None, reason="needs strace (a Debian package; scripts/setup-firmware-toolchain.sh "
                                           "installs it)")
def test_killed_at_write_system_calls_spread_over_a_whole_run(tmp_path):
    """SIGKILL on entering the N-th pwrite64 (strace fault injection), N from the first write
    (creating the file) to the last (closing it)."""
    total = count_writes(DRIVER + [str(tmp_path / "whole.h5")], tmp_path / "writes.log", env=ENV, cwd=ROOT)
    assert total > 100
    results = {}
    for n in sorted({1, 2, total - 1, total, *np.linspace(3, total - 2, 7).astype(int).tolist()}):
        out = tmp_path / f"w{n}.h5"
        assert kill_at_write(DRIVER + [str(out)], n, env=ENV, cwd=ROOT) != 0, f"not killed at write {n}"
        results[f"write {n}"] = check_recovered(out)
    _assert_all_recovered(results)


@pytest.mark.parametrize("where, points", [("append", (1, 15, 16, 150, APPENDS)), ("flush", (1, 2, 30, FLUSHES)),
                                           ("after-flush", (4, 5, 29, 53))])
def test_killed_inside_appends_and_flushes(tmp_path, where, points):
    """SIGKILL inside the K-th column append or file flush (as the writer enters it), or as
    the K-th flush returns (whole chunks just stored; flushes 5, 29 and 53 are those a sample
    block starts, with the block not yet handed on)."""
    import subprocess

    results = {}
    for k in points:
        out = tmp_path / f"{where}{k}.h5"
        option = "--kill-after-flush" if where == "after-flush" else f"--kill-at-{where}"
        res = subprocess.run(DRIVER + [str(out), option, str(k)], env=ENV, cwd=ROOT,
                             capture_output=True, text=True, timeout=120)
        assert res.returncode == -9, f"{where} {k}: {res.returncode} {res.stderr[-500:]}"
        results[f"{where} {k}"] = check_recovered(out)
    _assert_all_recovered(results)
