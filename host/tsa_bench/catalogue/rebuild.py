"""The run files are the truth: a catalogue rebuilt from them, and rows checked against them.

Contract: :func:`rebuild` reads every ``*.h5`` file directly in a folder (each in a
bounded child: :class:`~.runfiles.BoundedReader`) and writes its row (an existing row of
the same file keeps its id and verdict). It reports what it could not read, the rows
whose file changed since they were registered (the file wins), and the rows of that
folder whose file is gone (kept, never deleted: a file on a disk not mounted now is not
a run that never was). :func:`check` lists the rows of a folder whose file is missing or
changed, by size and time, and with ``verify`` by SHA-256 too.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from tsa_bench.catalogue.database import Catalogue
from tsa_bench.catalogue.rows import RunRow
from tsa_bench.catalogue.runfiles import BoundedReader


@dataclass
class RebuildReport:
    files: int = 0
    added: int = 0
    updated: int = 0
    unreadable: list[tuple[str, str]] = field(default_factory=list)   # (path, why)
    changed: list[RunRow] = field(default_factory=list)               # rows whose file changed
    missing: list[RunRow] = field(default_factory=list)               # rows whose file is gone


def run_files(folder: str | Path) -> list[Path]:
    """The ``*.h5`` regular files directly in ``folder``, by name (a run's name starts with its date)."""
    return sorted(p for p in Path(folder).glob("*.h5") if p.is_file())


def rebuild(cat: Catalogue, folder: str | Path, *, with_hash: bool = True,
            progress: Callable[[int, int], None] | None = None) -> RebuildReport:
    """Register every run file in ``folder`` from the file itself (module contract);
    ``with_hash=False`` skips the SHA-256 (a throw-away catalogue to search files once)."""
    report = RebuildReport()
    files = run_files(folder)
    known = {r.path: r for r in cat.search(folder=folder, newest_first=False)}
    with BoundedReader(with_hash=with_hash) as reader:
        for i, (path, facts, why) in enumerate(reader.read_all(files)):
            if facts is None:
                report.unreadable.append((str(path), why or "unreadable"))
                continue
            old = known.pop(facts["path"], None)
            if old is not None and old.sha256 and facts["sha256"] and old.sha256 != facts["sha256"]:
                report.changed.append(old)
            cat.upsert({**facts, "pid": None})
            report.files += 1
            if old is None:
                report.added += 1
            else:
                report.updated += 1
            if progress is not None:
                progress(i + 1, len(files))
    report.missing = [r for r in known.values() if not Path(r.path).exists()]
    return report


def check(cat: Catalogue, folder: str | Path | None = None, *, verify: bool = False) -> list[tuple[RunRow, str]]:
    """(row, state) of every row (of ``folder``) whose file is not what was registered."""
    rows = cat.search(folder=folder)
    states = [(r, r.verify() if verify else r.file_state()) for r in rows]
    return [(r, s) for r, s in states if s not in ("ok", "running", "elsewhere")]
