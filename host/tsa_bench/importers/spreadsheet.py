"""Excel workbooks (.xlsx) through openpyxl (the optional extra ``xlsx``).

Contract of :func:`read_xlsx`: the sheet ``sheet`` (default the first) is read with the
cached values of formulas; empty rows are skipped; a preamble, the header and a
headerless sheet are found as in a text file (:func:`.text.layout`); rows may be shorter
than the header (Excel drops trailing empty cells: they are empty) but not longer.
Messages name the sheet and the spreadsheet row (``file:sheet 'Data' row 12``).
"""

from __future__ import annotations

import datetime as dt
import zipfile
from pathlib import Path

import numpy as np

from tsa_bench.importers.errors import SUPPORTED, ImportFileError
from tsa_bench.importers.table import Column, SourceTable, numbers
from tsa_bench.importers.text import layout
from tsa_bench.store.budget import check_budget

#: Memory per byte of unpacked worksheet XML while its cells are read (Python objects per cell).
XML_FACTOR = 3


def _text(v: object) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "1" if v else "0"
    if isinstance(v, (int, float)):
        return repr(float(v))
    if isinstance(v, (dt.datetime, dt.date, dt.time, dt.timedelta)):
        return f"{v} (a date or time cell: give time as a number of seconds)"
    return str(v).strip()


def read_xlsx(path: Path, sheet: str | None, no_header: bool) -> SourceTable:
    """Read one worksheet into a :class:`SourceTable` (module contract)."""
    try:
        import openpyxl
    except ImportError:
        raise ImportFileError(f"{path}: an Excel workbook; reading it needs the optional extra 'xlsx' "
                              "(pip install 'tsa-bench[xlsx]', which installs openpyxl)") from None
    try:
        with zipfile.ZipFile(path) as z:   # the sheets' sizes once unpacked, from the zip directory
            unpacked = sum(i.file_size for i in z.infolist() if i.filename.startswith("xl/worksheets/"))
    except (zipfile.BadZipFile, OSError, ValueError):
        unpacked = 0   # load_workbook below says what is wrong
    check_budget(unpacked * XML_FACTOR, str(path), "its worksheets")
    try:
        wb = openpyxl.load_workbook(path, read_only=True, data_only=True)
    except MemoryError:
        raise
    except Exception as exc:  # openpyxl raises many kinds on a damaged zip or workbook
        raise ImportFileError(f"{path}: looks like an Excel workbook (.xlsx) but cannot be read "
                              f"({type(exc).__name__}: {exc}); supported formats: {SUPPORTED}") from None
    try:
        if sheet is not None and sheet not in wb.sheetnames:
            raise ImportFileError(f"{path}: no sheet '{sheet}' (sheets: {', '.join(wb.sheetnames)})")
        ws = wb[sheet] if sheet is not None else wb.worksheets[0]
        records = []
        for k, row in enumerate(ws.iter_rows(values_only=True), start=1):
            cells = [_text(v) for v in row]
            while cells and not cells[-1]:
                cells.pop()
            if cells:
                records.append((k, cells))
    finally:
        wb.close()
    first, header, width, notes = layout(records[:40], no_header, False, path)
    notes.insert(0, f"sheet '{ws.title}'" + (f" of {len(wb.sheetnames)} ({', '.join(wb.sheetnames)}; --sheet)"
                                              if len(wb.sheetnames) > 1 else ""))
    body = records[first:]
    errors = [f"{path}:sheet '{ws.title}' row {k}: {len(c)} cells, the header has {width}"
              for k, c in body if len(c) > width][:20]
    if errors:
        raise ImportFileError("\n".join(errors))
    columns = []
    names = header if header is not None else [""] * width
    for i in range(width):
        vals, bad, n_bad = numbers([c[i] if i < len(c) else "" for _, c in body])
        columns.append(Column(names[i], vals, bad, n_bad))
    header_line = records[first - 1][0] if header is not None else None
    return SourceTable(path, "xlsx", columns, np.array([k for k, _ in body], int), header_line, header is not None,
                       notes, row_prefix=f"sheet '{ws.title}' row ")
