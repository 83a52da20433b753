"""Checks on the chosen columns' values before anything is written (all problems named at once)."""

from __future__ import annotations

import numpy as np

from tsa_bench.importers.columns import Choice
from tsa_bench.importers.errors import ImportFileError
from tsa_bench.importers.table import SourceTable
from tsa_bench.rundocs import SAMPLE_COLUMNS
from tsa_bench.store.reader import MAX_ABS_VALUE

MAX_ERRORS = 20


def converted(table: SourceTable, chosen: list[Choice]) -> dict[str, np.ndarray]:
    """{target: values in the stored unit} after checking every cell (up to 20 problems named).

    Cells that are not numbers, NaN in ``t`` or in integer columns, integers that are not
    whole or do not fit their column's type (never wrapped), and values beyond 1e15 in
    magnitude after conversion are refused."""
    errors: list[str] = []
    out: dict[str, np.ndarray] = {}
    for c in chosen:
        col = table.columns[c.index]
        what = f"column {table.label(c.index)} ({c.target})"
        for k, cell in col.bad:
            errors.append(f"{table.where(k)}: {what}: cannot parse '{cell}' as a number")
        v = col.values
        dtype = SAMPLE_COLUMNS[c.target][0] if c.target in SAMPLE_COLUMNS else "f8"
        integer = dtype[0] in "iu"
        bad = np.zeros(len(v), bool)
        for k in col.bad:
            bad[k[0]] = True
        nonfinite = ~np.isfinite(v) & ~bad
        if c.target == "t" or integer:
            for k in np.flatnonzero(nonfinite)[:MAX_ERRORS]:
                errors.append(f"{table.where(int(k))}: {what}: empty or {v[k]!r} where a finite value is required")
        else:
            for k in np.flatnonzero(np.isinf(v))[:MAX_ERRORS]:
                errors.append(f"{table.where(int(k))}: {what}: {v[k]!r} where a finite value is required")
        fin = np.isfinite(v)
        if integer:
            info = np.iinfo(dtype)
            for k in np.flatnonzero(fin & (v != np.round(v)))[:MAX_ERRORS]:
                errors.append(f"{table.where(int(k))}: {what}: '{v[k]:g}' is not a whole number")
            for k in np.flatnonzero(fin & ((v < info.min) | (v > info.max)))[:MAX_ERRORS]:
                errors.append(f"{table.where(int(k))}: {what}: {v[k]:g} does not fit {c.target} ({info.min}..{info.max})")
        w = v * c.factor + c.offset if (c.factor != 1.0 or c.offset != 0.0) else v
        for k in np.flatnonzero(np.isfinite(w) & (np.abs(w) > MAX_ABS_VALUE))[:MAX_ERRORS]:
            errors.append(f"{table.where(int(k))}: {what}: {v[k]:g} is too large (at most {MAX_ABS_VALUE:g} in magnitude)")
        out[c.target] = w
        if len(errors) >= MAX_ERRORS:
            break
    if errors:
        more = " (stopped after the first errors)" if len(errors) >= MAX_ERRORS else ""
        raise ImportFileError("\n".join(errors[:MAX_ERRORS]) + more)
    if table.n_rows == 0:
        raise ImportFileError(f"{table.path}: no data rows after the header")
    return out
