"""A run file damaged so that the HDF5 library itself loops is refused, not hung on."""

from __future__ import annotations

import h5py
import pytest
from click.testing import CliRunner

from tests.runner.helpers import plan_from_text, run_plan
from tests.store.hostile import looping_file
from tsa_bench.cli import main
from tsa_bench.store import RunFileError, read_run
from tsa_bench.store import probe
from tsa_bench.store.listing import list_runs

PLAN = """name: short
defaults: {rate_turns_per_s: 2, accel_turns_per_s2: 20}
steps:
  - move_to: {turns: 3}
  - hold: {duration_s: 2}
"""
def _damaged(path):
    """A small HDF5 file whose global heap's first object has a wrong size (top bit of its
    size field flipped): HDF5 1.14 then loops on every read of its string attributes (found
    by the mutation tests; built by tests/store/hostile.py from fixed contents)."""
    return looping_file(path)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("damaged")
    stop, _, path = run_plan(plan_from_text(PLAN), d)
    assert stop.exit_status == "success"
    return path, _damaged(d / "damaged.h5")


@pytest.fixture
def short_timeout(monkeypatch):
    """A damaged file is given up on after 2 s instead of 20 (a good one takes milliseconds)."""
    monkeypatch.setattr(probe, "TIMEOUT_S", 2.0)


def test_a_good_file_passes_the_probe_and_is_read(files):
    good, _ = files
    assert probe.check_hdf5_terminates(good) is None
    assert len(read_run(good)) > 10


def test_the_probe_names_a_damaged_file(files, short_timeout):
    why = probe.check_hdf5_terminates(files[1])
    assert why is not None and why.startswith("damaged HDF5 file")


def test_readers_refuse_it_with_the_file_and_the_reason(files, short_timeout):
    good, bad = files
    with pytest.raises(RunFileError, match=r"damaged\.h5: damaged HDF5 file"):
        read_run(bad)
    lines = {line.path.name: line for line in list_runs(bad.parent)}
    assert "damaged HDF5 file" in (lines["damaged.h5"].problem or "")


@pytest.mark.parametrize("command", [["info"], ["report"], ["export", "--csv"]])
def test_commands_exit_2_naming_the_damage(files, command, short_timeout):
    _, bad = files
    before = bad.read_bytes()
    res = CliRunner().invoke(main, [*command, str(bad)] if command[0] != "export" else ["export", str(bad), "--csv"])
    assert res.exit_code == 2, res.output
    assert "damaged HDF5 file" in res.output and "Traceback" not in res.output
    assert bad.read_bytes() == before


def test_with_other_threads_running_the_probe_uses_a_fresh_interpreter(files, short_timeout, monkeypatch):
    """A fork while another thread holds h5py's lock would leave the child waiting for ever."""
    import threading

    monkeypatch.setattr(threading, "active_count", lambda: 3)
    monkeypatch.setattr(probe.os, "fork", lambda: pytest.fail("forked with other threads running"))
    good, bad = files
    assert probe.check_hdf5_terminates(good) is None
    assert probe.check_hdf5_terminates(bad).startswith("damaged HDF5 file")
