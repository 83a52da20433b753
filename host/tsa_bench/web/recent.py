"""The page's view of the run catalogue: recent runs with search, and facts about live runs.

Contract: :class:`CatalogueView` opens the catalogue lazily and only to read it. A SQLite
catalogue that does not exist yet is not created (the first recorded run creates it; the
view says so and looks again on the next call); one that cannot be opened is said in
``problem``, never raised, so the live board works without any catalogue. Searches take
the words of a search box: ``sample=S3 load_g>=200 plan~life`` (the conditions of
``tsa-bench ls --where``), a word without an operator matches file paths containing it.
Every call is a short read: SQLite in WAL mode and PostgreSQL never make a writer wait
for a reader.
"""

from __future__ import annotations

import shlex
import threading
from pathlib import Path
from typing import Any

from tsa_bench.catalogue import CATALOGUE_FILE, Catalogue, CatalogueError, RunRow, WhereError, open_catalogue, shown_url
from tsa_bench.catalogue.where import OPERATORS

#: Rows a search returns at most.
MAX_ROWS = 500


def sqlite_file(target: str) -> Path | None:
    """The SQLite file a catalogue target names, or None for a server URL."""
    if target.startswith("sqlite:///"):
        return Path(target[len("sqlite:///"):])
    if "://" in target:
        return None
    path = Path(target)
    return path / CATALOGUE_FILE if path.is_dir() else path


def conditions(query: str) -> list[str]:
    """The search box's words as catalogue conditions (module contract); WhereError on bad quoting."""
    try:
        words = shlex.split(query)
    except ValueError as exc:
        raise WhereError(f"search {query!r}: {exc}") from None
    return [w if any(op in w for op in OPERATORS) else f"path~{w}" for w in words]


def row_json(row: RunRow) -> dict[str, Any]:
    """A row for the page: every field, and whether its file is still the one registered."""
    return {**row.as_dict(), "name": row.name, "file_state": row.file_state()}


class CatalogueView:
    """Read access to one catalogue (module contract)."""

    def __init__(self, target: str) -> None:
        self.target = target
        self.shown = shown_url(target) if "://" in target else target
        self.problem: str | None = None
        self._cat: Catalogue | None = None
        self._lock = threading.Lock()

    def _open(self) -> Catalogue | None:
        with self._lock:
            if self._cat is not None:
                return self._cat
            path = sqlite_file(self.target)
            if path is not None and not path.exists():
                self.problem = f"no catalogue yet at {path} (the first run recorded there creates it)"
                return None
            try:
                self._cat = open_catalogue(self.target, retry_s=5.0)
                self.problem = None
            except CatalogueError as exc:
                self.problem = str(exc)
            return self._cat

    def _call(self, what):
        cat = self._open()
        if cat is None:
            return None
        try:
            return what(cat)
        except CatalogueError as exc:
            self.problem = str(exc)
            return None

    def search(self, query: str = "", status: str | None = None, since: str | None = None,
               limit: int = 50) -> dict[str, Any]:
        """``{"rows": [...], "problem": str|None, "catalogue": shown}``, or ``{"error": why}`` for a bad search."""
        try:
            conds = conditions(query)
            rows = self._call(lambda cat: cat.search(conds, status=status or None, since=since or None,
                                                     limit=max(1, min(int(limit), MAX_ROWS))))
        except WhereError as exc:
            return {"error": str(exc), "catalogue": self.shown}
        return {"rows": [row_json(r) for r in rows or []], "problem": self.problem, "catalogue": self.shown}

    def running(self) -> list[RunRow]:
        """The rows still recording (their sidecars are what the board follows)."""
        return self._call(lambda cat: cat.search(status="running", limit=MAX_ROWS)) or []

    def get(self, run_id: int) -> RunRow | None:
        return self._call(lambda cat: cat.get(run_id))

    def by_path(self, path: str | Path) -> RunRow | None:
        return self._call(lambda cat: cat.by_path(path))

    def close(self) -> None:
        with self._lock:
            if self._cat is not None:
                self._cat.close()
                self._cat = None
