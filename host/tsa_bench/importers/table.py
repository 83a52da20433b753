"""The form every reader hands on: named columns of float64 values and where each row came from."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class Column:
    """One source column: ``values`` float64 (NaN where empty or ``nan``), ``bad`` up to 20
    (row index, cell text) that are not numbers, ``n_bad`` how many there are in all, ``unit``
    a unit the format itself gives (a TDMS ``unit_string``), else ""."""

    name: str
    values: np.ndarray
    bad: list[tuple[int, str]] = field(default_factory=list)
    n_bad: int = 0
    unit: str = ""


@dataclass
class SourceTable:
    """A source file read into columns. ``header_line`` is the 1-based line (or row) of the
    header, None without one; ``row_lines`` the line (row) number of each data row, for
    messages (a ``range`` when the rows are consecutive lines); ``where`` the prefix of a message about a data row (``file:line``)."""

    path: Path
    fmt: str
    columns: list[Column]
    row_lines: np.ndarray | range
    header_line: int | None = None
    has_header: bool = True
    notes: list[str] = field(default_factory=list)
    time_s: np.ndarray | None = None  # time the format carries apart from the columns (TDMS waveforms)
    row_prefix: str = ""  # before the row number in messages: "sheet 'Data' row ", "row "

    @property
    def n_rows(self) -> int:
        return len(self.row_lines)

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.columns]

    def where(self, row: int | None = None) -> str:
        if row is None:
            return f"{self.path}:{self.row_prefix}{self.header_line}" if self.header_line else str(self.path)
        return f"{self.path}:{self.row_prefix}{int(self.row_lines[row])}"

    def label(self, i: int) -> str:
        """How column ``i`` is named in messages: its header text, or its 1-based position."""
        name = self.columns[i].name
        return f"'{name}'" if self.has_header and name else f"{i + 1}"


def numbers(cells: list[str] | np.ndarray, decimal_comma: bool = False) -> tuple[np.ndarray, list[tuple[int, str]], int]:
    """Parse text cells as float64: empty and ``nan`` are NaN. Returns (values, up to 20
    (index, text) that are not numbers, how many are not). Vectorised; per cell only on failure."""
    a = np.asarray(cells, dtype=str)
    if decimal_comma:
        a = np.char.replace(a, ",", ".")
    empty = a == ""
    if empty.any():
        a = np.where(empty, "nan", a)  # np.where widens the dtype: 'nan' is not cut to the cells' width
    try:
        return a.astype(np.float64), [], 0
    except ValueError:
        pass
    out = np.empty(len(a), dtype=np.float64)
    bad: list[tuple[int, str]] = []
    n_bad = 0
    for k, cell in enumerate(a.tolist()):
        try:
            out[k] = float(cell) if cell.strip() else np.nan
        except ValueError:
            out[k] = np.nan
            n_bad += 1
            if len(bad) < 20:
                bad.append((k, str(cells[k])))
    return out, bad, n_bad
