"""`tsa-bench ls DIR`: one line per run file in a folder, read from attributes only.

Contract: :func:`list_runs` looks at the ``*.h5`` regular files directly in a folder
(sorted by name, which starts with the run's date) and reads of each only its root
attributes, the lengths of ``/samples/t`` and ``/segments`` and the ``completed`` flags
of ``/segments`` (within the memory budget; never the sample data, so a folder of long runs
lists at once): status, plan, device duration, samples, segments
completed, the link to a run it resumes or that continues it. A run whose live sidecar
is still written by a living process is "recording"; a killed one (status "running",
writer gone) is "killed". A file that is not a readable run file is listed with why.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from tsa_bench.store.budget import OverBudget, check_budget
from tsa_bench.userfiles import DocumentError, check_regular_file
from tsa_bench.store.hdf5 import FORMAT
from tsa_bench.store.live import recording
from tsa_bench.store.probe import check_hdf5_terminates


@dataclass(frozen=True)
class RunLine:
    path: Path
    status: str
    plan: str = ""
    duration_s: float = float("nan")
    samples: int = 0
    segments: str = ""
    created: str = ""
    link: str = ""
    problem: str = ""


def _text(value) -> str:
    if isinstance(value, bytes):
        return value.decode(errors="replace")
    if isinstance(value, np.generic):
        return str(value.item())
    return str(value)


def _one(path: Path) -> RunLine:
    try:
        check_regular_file(path, "run file")
    except DocumentError as exc:
        return RunLine(path, "?", problem=exc.message)
    if recording(path):
        return RunLine(path, "recording", problem="being recorded (tsa-bench watch shows it)")
    why = check_hdf5_terminates(path)
    if why:
        return RunLine(path, "?", problem=why)
    try:
        with h5py.File(path, "r") as f:
            a = f.attrs
            if _text(a.get("format", "")) != FORMAT:
                return RunLine(path, "?", problem="not a tsa-bench run file")
            status = _text(a.get("exit_status", "?"))
            samples = f["samples/t"].shape[0] if "samples/t" in f else 0
            segs = ""
            if "segments" in f and f["segments"].dtype.names and "completed" in f["segments"].dtype.names:
                seg = f["segments"]
                check_budget(float(seg.shape[0]) * seg.dtype.itemsize, str(path), "/segments")
                segs = str(int(np.count_nonzero(seg["completed"][()])))
                if "n_segments" in a:
                    segs += f"/{int(a['n_segments'])}"
            duration = float(a["duration_s"]) if "duration_s" in a else (
                float(f["samples/t"][-1]) if samples else float("nan"))
            link = ""
            if "resumed_from" in a:
                link = f"resumes {_text(a['resumed_from'])} from segment {_text(a.get('first_segment', '?'))}"
            if "continued_in" in a:
                link = (link + "; " if link else "") + f"continued in {_text(a['continued_in'])}"
            return RunLine(path, "killed" if status == "running" else status, _text(a.get("plan_name", "")),
                           duration, samples, segs, _text(a.get("created", "")), link)
    except OverBudget as exc:
        return RunLine(path, "?", problem=str(exc).removeprefix(f"{path}: "))
    except Exception as exc:  # h5py reports damaged files with many exception types
        return RunLine(path, "?", problem=f"not a readable HDF5 file ({type(exc).__name__})")


def run_line(path: str | Path) -> RunLine:
    """The line of one run file (as :func:`list_runs` gives it)."""
    return _one(Path(path))


def list_runs(folder: str | Path) -> list[RunLine]:
    """Every ``*.h5`` run file directly in ``folder`` (module contract)."""
    root = Path(folder)
    return [_one(p) for p in sorted(root.glob("*.h5")) if not p.is_symlink() or p.exists()]
