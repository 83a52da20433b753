"""A disk that fills: at the start (refused, nothing written) and during a run (STOP,
"failed: disk full", exit 1, a file that reads back). Two ways to a full disk: a file
size limit (RLIMIT_FSIZE, any machine, no root) and a small tmpfs (where this machine
lets a private mount namespace mount one)."""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.faults.ptybench import ROOT
from tsa_bench import catalogue
from tsa_bench.store import read_run

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_FSIZE semantics and tmpfs are Linux's")
ENV = {k: v for k, v in os.environ.items() if k != catalogue.ENV_VAR} | {"PYTHONPATH": str(ROOT / "host")}
LIFETIME = str(ROOT / "configs/protocols/lifetime.yaml")  # ~100,000 samples: ~13 MB with its sidecar


def _limited(limit_bytes: int):
    def preexec() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
    return preexec


def _cli(*args: str, limit_bytes: int | None = None, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tsa_bench.cli", *args], env=ENV, cwd=cwd, capture_output=True,
                          text=True, timeout=300, preexec_fn=_limited(limit_bytes) if limit_bytes else None)


def test_no_room_at_the_start_is_refused_before_anything_is_written(tmp_path):
    out = tmp_path / "r.h5"
    res = _cli("run", LIFETIME, "--output", str(out), limit_bytes=2_000_000)
    assert res.returncode == 1, res.stdout + res.stderr
    assert "disk full" in res.stderr and "nothing was run" in res.stderr and "Traceback" not in res.stderr
    assert not out.exists() and not out.with_name("r.h5.live").exists()


#: Runs `tsa-bench run` with the start check's estimate cut a hundredfold, so the run
#: starts and the disk fills while it records (as when another program eats the space);
#: written uncompressed, so that the lifetime run's file (about 1 MB compressed) reaches the limit.
FILL_MID_RUN = (
    "import runpy, sys\n"
    "from tsa_bench.store import space\n"
    "real = space.run_bytes\n"
    "space.run_bytes = lambda samples, segments: real(samples / 100, segments // 100)\n"
    "from tsa_bench.store import hdf5\n"   # uncompressed: the file outgrows the limit mid-run
    "hdf5.RunWriter.__init__.__kwdefaults__['compression_level'] = 0\n"
    "sys.argv = ['tsa-bench', 'run', *sys.argv[1:]]\n"
    "runpy.run_module('tsa_bench.cli', run_name='__main__')\n")


def test_the_disk_filling_up_mid_run_ends_it_failed_with_a_readable_file(tmp_path):
    """A file size limit of 4 MB that the run reaches while it records: STOP, "failed:
    disk full", exit 1, and a file that reads back with every row whole."""
    out = tmp_path / "r.h5"
    res = subprocess.run([sys.executable, "-c", FILL_MID_RUN, LIFETIME, "--output", str(out)], env=ENV,
                         capture_output=True, text=True, timeout=300, preexec_fn=_limited(4_000_000))
    assert res.returncode == 1, res.stdout + res.stderr
    assert "run failed: disk full" in res.stderr and "Traceback" not in res.stderr, res.stderr
    assert "live view disabled" not in res.stderr   # the run stopped before its journal ran out of room
    run = read_run(out)  # read without the limit: every column the same length
    assert run.exit_status == "failed" and run.attrs["reason"].startswith("disk full"), run.attrs["reason"]
    assert len(run) > 10_000 and os.path.getsize(out) <= 4_000_000
    assert "stop_sent" in {k.decode() for k in run.events["kind"]}
    info = _cli("info", str(out))
    assert info.returncode == 0 and "failed: disk full" in info.stdout, info.stdout + info.stderr
    # the journal went with the closed file; the folder's catalogue lists the run as failed
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["r.h5", catalogue.CATALOGUE_FILE])
    with catalogue.open(tmp_path) as cat:
        assert [(Path(r.path).name, r.status) for r in cat.search()] == [("r.h5", "failed")]
    watch = _cli("watch", str(out), "--plain", "--wait", "0")
    assert watch.returncode == 1 and "run ended: failed (disk full" in watch.stdout, watch.stdout + watch.stderr
    csv = tmp_path / "csv"   # and an export onto the full disk: an error, no truncated CSV
    res = _cli("export", str(out), "--csv", "--out", str(csv), limit_bytes=1_000_000)
    assert res.returncode == 1 and "cannot write the CSV files" in res.stderr and "Traceback" not in res.stderr, \
        res.stderr
    assert list(csv.iterdir()) == []


def test_a_file_size_limit_the_journal_reaches_first_stops_the_run_with_both_files_whole(tmp_path):
    """Compressed, the run file is about a tenth of its journal, so under a file size limit
    the journal reaches it first: the run stops "failed: disk full" while the journal can
    still be closed (never switched off mid-run), and the file reads back whole."""
    out = tmp_path / "r.h5"
    script = FILL_MID_RUN.replace("hdf5.RunWriter.__init__.__kwdefaults__['compression_level'] = 0\n", "")
    res = subprocess.run([sys.executable, "-c", script, LIFETIME, "--output", str(out)], env=ENV,
                         capture_output=True, text=True, timeout=300, preexec_fn=_limited(5_000_000))
    assert res.returncode == 1, res.stdout + res.stderr
    assert "run failed: disk full: journaling" in res.stderr and "live view disabled" not in res.stderr, res.stderr
    run = read_run(out)
    assert run.exit_status == "failed" and len(run) > 10_000 and not out.with_name("r.h5.live").exists()


def test_a_small_tmpfs_filling_up_mid_run(tmp_path):
    """The real thing: a 3 MiB tmpfs in a private mount namespace (skipped where the
    machine does not allow mounting one)."""
    unshare = shutil.which("unshare")
    if unshare is None:
        pytest.skip("no unshare(1) to make a private mount namespace")
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    as_user = [] if os.geteuid() == 0 else ["--user", "--map-root-user"]
    probe = subprocess.run([unshare, *as_user, "--mount", "sh", "-c", f"mount -t tmpfs -o size=3m tmpfs {mnt}"],
                           capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {probe.stderr.strip()}")
    shell = (f"mount -t tmpfs -o size=3m tmpfs {mnt} && cd {tmp_path} && "
             f"{sys.executable} -c \"$SCRIPT\" {LIFETIME} --output {mnt}/r.h5; code=$?; cp {mnt}/r.h5 {tmp_path}/copy.h5; "
             f"{sys.executable} -m tsa_bench.cli run {LIFETIME} --output {mnt}/again.h5 2> {tmp_path}/again.txt; "
             f"echo $? >> {tmp_path}/again.txt; exit $code")
    res = subprocess.run([unshare, *as_user, "--mount", "sh", "-c", shell], env={**ENV, "SCRIPT": FILL_MID_RUN},
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 1, res.stdout + res.stderr
    assert "run failed: disk full" in res.stderr and "Traceback" not in res.stderr, res.stderr
    run = read_run(tmp_path / "copy.h5")
    assert run.exit_status == "failed" and "disk full" in run.attrs["reason"] and len(run) > 1000
    again = (tmp_path / "again.txt").read_text()  # the disk is full now: refused at the start
    assert "disk full" in again and "nothing was run" in again and again.strip().endswith("1"), again
