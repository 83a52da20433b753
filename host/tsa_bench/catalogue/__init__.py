"""The run catalogue: every run in one searchable table (SQLite beside the runs, or a shared PostgreSQL).

The read side, for a command or a web page::

    from tsa_bench import catalogue

    with catalogue.open("runs") as cat:                 # runs/catalogue.sqlite (or a URL:
        rows = cat.search(["sample=S3", "load_g>=200"],  #   "postgresql://lab@db/tsa")
                          status="success", since="2026-11-01", limit=50)
        row = cat.get(17)                                # a RunRow, or None
        row.path, row.status, row.load_g, row.meta       # fields: tsa_bench.catalogue.schema
        row.file_state()                                 # "ok" | "missing" | "changed" | "running" | "elsewhere"
        row.live_path                                    # RUN.h5.live while it records
        row.as_dict()                                    # JSON-ready

A running row's samples come from its live sidecar (:class:`tsa_bench.store.live.LiveTail`
on ``row.live_path``), which the recording process writes; the catalogue holds no samples.

The write side: :class:`~.recorder.CatalogueRecorder` (a run consumer a command attaches;
the runner never imports this room), :meth:`Catalogue.upsert`, :meth:`Catalogue.set_verdict`,
and :func:`~.rebuild.rebuild` from the run files, which stay the truth.

Modules: :mod:`.schema` (the table, the searchable fields), :mod:`.where` (conditions),
:mod:`.database` (opening, concurrent writes, search), :mod:`.rows` (:class:`RunRow`),
:mod:`.runfiles` (what a run file says), :mod:`.recorder`, :mod:`.rebuild`.
"""

from __future__ import annotations

from pathlib import Path

from tsa_bench.catalogue.database import (
    CATALOGUE_FILE, ENV_VAR, Catalogue, CatalogueError, default_target, open_catalogue, shown_url,
)
from tsa_bench.catalogue.rows import RunRow
from tsa_bench.catalogue.schema import FIELDS
from tsa_bench.catalogue.where import WhereError

__all__ = ["CATALOGUE_FILE", "ENV_VAR", "FIELDS", "Catalogue", "CatalogueError", "RunRow", "WhereError",
           "default_target", "open", "open_catalogue", "shown_url"]


def open(target: str | Path) -> Catalogue:  # noqa: A001 (catalogue.open reads as intended)
    """The catalogue at a URL, a SQLite file or a folder of runs (its catalogue.sqlite)."""
    return open_catalogue(target)
