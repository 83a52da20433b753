"""The run-file reader accepts any file meeting the contract and names every violation."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from tsa_bench.store import REQUIRED_COLUMNS, RunFileError, read_run


def write_minimal(path, n=5, drop=None, units=None, short=None, extra=False):
    """A run file as another tool might write it: only what the contract requires."""
    with h5py.File(path, "w") as f:
        f.attrs["format"] = "tsa-bench/run"
        f.attrs["exit_status"] = "success"
        g = f.create_group("samples")
        for name, unit in REQUIRED_COLUMNS.items():
            if name == drop:
                continue
            ds = g.create_dataset(name, data=np.arange(n - (1 if name == short else 0), dtype=float))
            ds.attrs["units"] = (units or {}).get(name, unit)
        if extra:
            g.create_dataset("temperature", data=np.full(n, 25.0)).attrs["units"] = "degC"


def test_a_minimal_file_from_another_tool_is_read(tmp_path):
    write_minimal(tmp_path / "m.h5", extra=True)
    run = read_run(tmp_path / "m.h5")
    assert len(run) == 5 and run.exit_status == "success" and run.segments is None
    assert run.units["temperature"] == "degC" and np.array_equal(run.t_s, np.arange(5.0))


@pytest.mark.parametrize("kwargs, message", [
    ({"drop": "resistance"}, "lacks the required column(s) ['resistance']"),
    ({"units": {"length": "cm"}}, "/samples/length has units 'cm', the contract says 'mm'"),
    ({"short": "load"}, "differ in length"),
])
def test_contract_violations_are_named(tmp_path, kwargs, message):
    write_minimal(tmp_path / "bad.h5", **kwargs)
    with pytest.raises(RunFileError) as info:
        read_run(tmp_path / "bad.h5")
    assert message in str(info.value) and "bad.h5" in str(info.value)


def test_wrong_format_and_missing_samples(tmp_path):
    with h5py.File(tmp_path / "a.h5", "w") as f:
        f.attrs["format"] = "tsa-bench/run"
    with pytest.raises(RunFileError, match="no /samples group"):
        read_run(tmp_path / "a.h5")
    with h5py.File(tmp_path / "b.h5", "w") as f:
        f.attrs["format"] = "other"
    with pytest.raises(RunFileError, match="'format' is 'other'"):
        read_run(tmp_path / "b.h5")
