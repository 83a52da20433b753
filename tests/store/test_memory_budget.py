"""Files declaring more data than they hold are refused unread, within a memory budget;
the probe reads metadata and bounded slices only, and gives up on a looping library after
a CPU-time limit. (scripts/bench/hostile_files.py prints the times and memory.)"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from tests.importers import fixtures
from tests.store.hostile import huge_matlab_file, huge_run_file, looping_file
from tsa_bench.cli import main
from tsa_bench.rundocs import SAMPLE_COLUMNS, RunStart, RunStop, SampleBlock
from tsa_bench.store import RunFileError, RunWriter, probe, read_run
from tsa_bench.store.budget import parse_size, set_memory_budget

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "host")}
ENV.pop("TSA_BENCH_MAX_MEMORY", None)
LIMIT = 1 << 30   # address space of the command under test: reading what the files declare would not fit


def _limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT, LIMIT))


def _cli(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tsa_bench.cli", *args], cwd=cwd, env=ENV, capture_output=True,
                          text=True, timeout=300, preexec_fn=_limited)


def _refused(res: subprocess.CompletedProcess, name: str) -> None:
    text = res.stdout + res.stderr
    assert res.returncode == 2 and "Traceback" not in text and "MemoryError" not in text, text
    assert f"{name}: reading" in text and "memory budget" in text and "--max-memory" in text, text


@pytest.fixture(scope="module")
def hostile(tmp_path_factory):
    d = tmp_path_factory.mktemp("hostile")
    huge_run_file(d / "huge.h5")
    huge_matlab_file(d / "huge.mat")
    return d


@pytest.mark.parametrize("command", [["info", "huge.h5"], ["report", "huge.h5", "--out", "rep"],
                                     ["export", "huge.h5", "--csv", "--out", "csv"],
                                     ["fit", "self-sensing", "huge.h5", "--out", "m.json"],
                                     ["diagnose", "huge.h5", "--out", "diag"]])
def test_a_run_file_declaring_twenty_million_row_columns_is_refused_unread(hostile, command):
    assert (hostile / "huge.h5").stat().st_size < 100_000
    _refused(_cli(hostile, *command), "huge.h5")
    assert sorted(p.name for p in hostile.iterdir()) == ["huge.h5", "huge.mat"]   # nothing written


def test_a_matlab_file_declaring_three_billion_values_is_refused_unread(hostile):
    assert (hostile / "huge.mat").stat().st_size < 4096
    _refused(_cli(hostile, "import", "huge.mat", "--out", "x.h5"), "huge.mat")
    assert not (hostile / "x.h5").exists()


def _small_run(path: Path, rows: int = 5000) -> Path:
    w = RunWriter(path)
    w.on_start(RunStart("p", "name: p\n", None, "b: 1\n", None, "sim", "sim://", "1.0.0", {}, 1, 1.0))
    cols = {name: np.arange(rows).astype(dtype) for name, (dtype, _) in SAMPLE_COLUMNS.items()}
    cols["t"] = np.arange(rows) * 1e-3
    w.on_samples(SampleBlock(cols))
    w.on_stop(RunStop("success", "done", rows * 1e-3, rows, 0, 0, 0.1))
    return path


def test_the_budget_counts_what_a_file_declares_and_max_memory_sets_it(tmp_path):
    path = _small_run(tmp_path / "run.h5")   # 5000 rows x 68 bytes = 340,000 bytes of columns
    res = CliRunner().invoke(main, ["info", str(path), "--max-memory", "300K"])
    assert res.exit_code == 2 and "memory budget of 300 KiB" in res.output and "--max-memory" in res.output
    res = CliRunner().invoke(main, ["info", str(path), "--max-memory", "400K"])
    assert res.exit_code == 0 and "5000" in res.output, res.output
    res = CliRunner().invoke(main, ["info", str(path), "--max-memory", "lots"])
    assert res.exit_code == 2 and "not a size" in res.output
    assert parse_size("8G") == 8 << 30 and parse_size("1.5M") == 1536 << 10


def _write_csv(path: Path) -> Path:
    path.write_text("t [s],turns [turn]\n" + "".join(f"{i * 0.1},{i}\n" for i in range(2000)))
    return path


@pytest.mark.parametrize("case", ["text", "xlsx", "mat5", "mat73", "tdms"])
def test_every_importer_checks_the_budget_before_reading(tmp_path, case):
    write = {"text": _write_csv,
             "xlsx": fixtures.write_xlsx, "mat5": fixtures.write_mat5, "mat73": fixtures.write_mat73,
             "tdms": fixtures.write_tdms}[case]
    if case in ("xlsx", "tdms"):
        pytest.importorskip({"xlsx": "openpyxl", "tdms": "nptdms"}[case])
    src = write(tmp_path / {"text": "a.csv", "mat5": "a.mat", "mat73": "b.mat"}.get(case, f"a.{case}"))
    res = CliRunner().invoke(main, ["import", str(src), "--out", str(tmp_path / "x.h5"), "--max-memory", "2K"])
    assert res.exit_code == 2 and "memory budget of 2 KiB" in res.output and "Traceback" not in res.output, res.output
    assert not (tmp_path / "x.h5").exists()


def test_a_memory_error_while_importing_is_a_clear_refusal(tmp_path, monkeypatch):
    from tsa_bench.importers import pipeline

    def no_memory(*_a, **_k):
        raise MemoryError()

    monkeypatch.setattr(pipeline, "converted", no_memory)
    src = tmp_path / "a.csv"
    src.write_text("t [s],turns [turn]\n0,0\n0.1,1\n")
    res = CliRunner().invoke(main, ["import", str(src), "--out", str(tmp_path / "x.h5")])
    assert res.exit_code == 2 and "not enough memory to import" in res.output, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit)
    assert not (tmp_path / "x.h5").exists()


def test_the_probe_gives_up_on_a_looping_library_after_its_cpu_limit(tmp_path):
    bad = looping_file(tmp_path / "loop.h5")
    why = probe.check_hdf5_terminates(bad)
    assert why is not None and "CPU time" in why and "loops" in why
    with pytest.raises(RunFileError, match="loop.h5: damaged HDF5 file"):
        read_run(bad)


def test_the_probe_reads_no_column_data(tmp_path, monkeypatch):
    """The probe reads attributes, chunk indexes, text tables and the end rows of everything
    else: never more than one value at a time of a sample column, however long."""
    path = _small_run(tmp_path / "run.h5", rows=100_000)
    reads: list[tuple[str, int]] = []
    real = h5py.Dataset.__getitem__

    def counted(self, key):
        value = real(self, key)
        reads.append((self.name, int(np.size(value))))
        return value

    monkeypatch.setattr(h5py.Dataset, "__getitem__", counted)
    probe._read_everything_small(path)   # what the probe's child runs
    columns = [(name, n) for name, n in reads if name.startswith("/samples/")]
    assert len({name for name, _ in columns}) == len(SAMPLE_COLUMNS) and max(n for _, n in columns) == 1
    assert ("/segments", 0) in reads or any(name == "/segments" for name, _ in reads)


def test_ls_reads_a_huge_segment_table_within_the_budget(tmp_path):
    huge_run_file(tmp_path / "huge.h5", rows=10, extras=0)
    with h5py.File(tmp_path / "huge.h5", "a") as f:
        f.create_dataset("segments", shape=(20_000_000,), maxshape=(None,), chunks=(4096,),
                         dtype=np.dtype([("index", "i4"), ("kind", "u1"), ("completed", "u1")]))
    res = CliRunner().invoke(main, ["ls", str(tmp_path), "--max-memory", "64M"])
    assert res.exit_code == 0 and "reading /segments would need" in res.output and "memory budget" in res.output, \
        res.output


@pytest.fixture(autouse=True)
def _default_budget():
    yield
    set_memory_budget(None)
