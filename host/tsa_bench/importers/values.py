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
        if col.bad and c.target == "t":
            errors.append(f"{table.where()}: {what}: t must be a number of seconds (a date or clock time cannot "
                          "be t: export elapsed seconds, or give --sample-period)")
        v = col.values
        dtype = SAMPLE_COLUMNS[c.target][0] if c.target in SAMPLE_COLUMNS else "f8"
        integer = dtype[0] in "iu"
        fin = np.isfinite(v)
        every = bool(fin.all())   # the common case: one pass decides that nothing below can fire
        if not every:
            bad = np.zeros(len(v), bool)
            for k in col.bad:
                bad[k[0]] = True
            if c.target == "t" or integer:
                for k in np.flatnonzero(~fin & ~bad)[:MAX_ERRORS]:
                    errors.append(f"{table.where(int(k))}: {what}: empty or {v[k]:g} where a finite value is required")
            else:
                for k in np.flatnonzero(np.isinf(v))[:MAX_ERRORS]:
                    errors.append(f"{table.where(int(k))}: {what}: {v[k]:g} where a finite value is required")
        if integer:
            info = np.iinfo(dtype)
            for k in np.flatnonzero(fin & (v != np.round(v)))[:MAX_ERRORS]:
                errors.append(f"{table.where(int(k))}: {what}: '{v[k]:g}' is not a whole number")
            for k in np.flatnonzero(fin & ((v < info.min) | (v > info.max)))[:MAX_ERRORS]:
                errors.append(f"{table.where(int(k))}: {what}: {v[k]:g} does not fit {c.target} ({info.min}..{info.max})")
        w = v * c.factor + c.offset if (c.factor != 1.0 or c.offset != 0.0) else v
        size = np.abs(w)
        if every and not size.max(initial=0.0) > MAX_ABS_VALUE:
            size = None
        for k in np.flatnonzero(np.isfinite(w) & (size > MAX_ABS_VALUE))[:MAX_ERRORS] if size is not None else ():
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
