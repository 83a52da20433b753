"""`import_csv`: the library entry of earlier versions, kept for scripts; see :mod:`tsa_bench.importers`."""

from __future__ import annotations

from pathlib import Path

from tsa_bench.importers import ImportFileError, ImportOptions, import_file

CsvImportError = ImportFileError


def import_csv(csv_path: str | Path, out_path: str | Path, mapping: dict[str, str] | None = None,
               units: dict[str, str] | None = None, meta: dict[str, str] | None = None,
               sample_period_s: float | None = None, **options: object) -> Path:
    """Convert one data file into a run file (:func:`tsa_bench.importers.import_file`); returns ``out_path``.

    No segments are inferred unless ``segments="infer"`` is given (the command line's default)."""
    opts = ImportOptions(mapping=mapping, units=dict(units or {}), meta=dict(meta or {}),
                         sample_period_s=sample_period_s, **options)  # type: ignore[arg-type]
    return import_file(csv_path, out_path, opts).path
