"""Kill a writer at a chosen write, then check its run is recovered with every journaled sample.

Shared by tests/store/test_kill_anywhere.py and scripts/fault_campaign.py. A kill at the
N-th ``pwrite64`` is delivered by strace's fault injection (``-e inject=pwrite64:signal=KILL:
when=N``): the process dies on entering that system call, whichever library call is making
it, which depends on nothing inside the writer. :func:`write_phases` names the HDF5 call
each write happens in (``strace -k`` stacks), so kills can be aimed inside flushes
(``H5Fflush``) and appends (``H5Dwrite``, ``H5Dset_extent``).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tsa_bench.store import RunFileError, read_run
from tsa_bench.store.live import LiveFormatError, LiveTail, sidecar_path
from tsa_bench.store.recover import RecoveryError, recover_run

STRACE = shutil.which("strace")
_CALL = re.compile(r"^(?:\d+\s+)?pwrite64\(", re.M)


@dataclass(frozen=True)
class Outcome:
    recoverable: bool     # recovered, and the run holds every sample, segment and event the journal held
                          # and every sample the run file held
    held: int             # samples the journal held at the kill (or the closed file, with no journal)
    recovered: int        # samples the recovered run holds that were journaled
    readable_as_is: bool  # the run file read before any recovery
    rebuilt: bool         # the run file did not read: the run was rebuilt into a new file
    detail: str


def strace_cmd(cmd: list[str], *, kill_at: int | None = None, stacks: bool = False, log: str = "/dev/null") -> list[str]:
    """``cmd`` under strace, tracing pwrite64 (and killing at the ``kill_at``-th one)."""
    args = [STRACE or "strace", "-f", "-qq", "-o", log, "-e", "trace=pwrite64"]
    if stacks:
        args.append("-k")
    if kill_at is not None:
        args += ["-e", f"inject=pwrite64:signal=KILL:when={kill_at}"]
    return args + cmd


def count_writes(cmd: list[str], log: Path, **kw) -> int:
    """How many pwrite64 calls ``cmd`` makes when it runs to the end."""
    subprocess.run(strace_cmd(cmd, log=str(log)), check=True, capture_output=True, **kw)
    return len(_CALL.findall(log.read_text(errors="replace")))


def write_phases(cmd: list[str], log: Path, **kw) -> list[str]:
    """For each pwrite64 of ``cmd`` (in order) the outermost HDF5 API call making it:
    "H5Fflush", "H5Dwrite", "H5Dset_extent", "H5Fclose", "H5Fcreate", ... or "?"."""
    subprocess.run(strace_cmd(cmd, stacks=True, log=str(log)), check=True, capture_output=True, **kw)
    phases = []
    for call in re.split(r"\n(?=(?:\d+\s+)?pwrite64\()", log.read_text(errors="replace")):
        if not _CALL.match(call):
            continue
        public = [name for name in re.findall(r"\((H5[A-Z][A-Za-z_]*)\+", call) if "_" not in name[3:]
                  or name in ("H5Dset_extent",)]
        phases.append(public[-1] if public else "?")
    return phases


def kill_at_write(cmd: list[str], n: int, **kw) -> int:
    """Run ``cmd``, SIGKILLed on entering its ``n``-th pwrite64; its return code."""
    return subprocess.run(strace_cmd(cmd, kill_at=n), capture_output=True, **kw).returncode


def _journal(path: Path) -> tuple[np.ndarray, list, list] | None:
    side = sidecar_path(path)
    if not side.is_file():
        return None
    tail = LiveTail(side, documents=True)
    try:
        parts = [value for kind, value in tail.items() if kind == "samples"]
        rec = np.concatenate(parts) if parts else np.zeros(0, dtype=tail.dtype)
        return rec, list(tail.segments), list(tail.events)
    finally:
        tail.close()


def check_recovered(path: Path) -> Outcome:
    """Recover the killed run at ``path`` (:func:`recover_run`) and compare it with what its
    journal held before: every sample (all carried columns), segment record and event."""
    try:
        journal = _journal(path)
    except (LiveFormatError, OSError) as exc:
        return Outcome(False, 0, 0, False, False, f"journal unreadable: {exc}")
    try:
        before = read_run(path).samples["counter"]
        as_is = True
    except RunFileError:
        before, as_is = None, False
    try:
        rec = recover_run(path)
        run = read_run(rec.path)
    except (RecoveryError, RunFileError) as exc:
        held = 0 if journal is None else len(journal[0])
        no_data = journal is None and not (path.exists() and path.stat().st_size)
        return Outcome(no_data, held, 0, as_is, False, f"not recovered: {exc}")
    if journal is None:   # the writer closed the file and deleted its journal: the file is the record
        return Outcome(run.exit_status != "running", len(run), len(run), as_is, rec.rebuilt,
                       f"closed {run.exit_status}")
    samples, segments, events = journal
    n = len(samples)
    problems = []
    if before is not None and not np.array_equal(run.samples["counter"][:len(before)], before):
        problems.append(f"the {len(before)} samples the run file held are not all in the recovered run")
    if len(run) != n:
        problems.append(f"{len(run)} samples, the journal held {n}")
    else:
        for name in samples.dtype.names[1:]:
            if not np.array_equal(run.samples[name], samples[name].astype(run.samples[name].dtype), equal_nan=True):
                problems.append(f"column {name} differs")
    got = [] if run.segments is None else [(int(r["index"]), r["kind"].decode(), float(r["t_end"]))
                                          for r in run.segments]
    want = [(int(s[0]), str(s[1]), float(s[3])) for s in segments]
    if got != want:
        problems.append(f"{len(got)} segment rows, the journal held {len(want)}")
    kinds = [] if run.events is None else [(r["kind"].decode(), r["detail"].decode()) for r in run.events]
    if [k for k in kinds if k[0] != "recovered"] != [(str(e[1]), str(e[2])) for e in events]:
        problems.append(f"events differ ({len(kinds)} in the run, {len(events)} journaled)")
    matched = int(min(len(run), n))
    return Outcome(not problems, n, matched if not problems else 0, as_is, rec.rebuilt,
                   "; ".join(problems) or rec.message)
