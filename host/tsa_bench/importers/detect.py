"""Which reader a source file needs: chosen by its content first, its suffix second.

Recognised by content: Excel workbooks (a zip holding ``xl/``), MATLAB v5 (``MATLAB 5.0
MAT-file`` header) and v7.3 (``MATLAB 7.3 MAT-file`` header in an HDF5 user block),
LabVIEW TDMS (``TDSm``), text (no NUL bytes in its first 64 KiB) unless named ``.m``
(MATLAB source, refused with the hint to save the workspace as .mat). Anything else - a
legacy ``.xls``, a zip that is not a workbook, a plain HDF5 file, other binary data - is
refused naming what it looks like and the formats supported (:data:`.errors.SUPPORTED`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tsa_bench.userfiles import DocumentError
from tsa_bench.userfiles.files import check_regular_file
from tsa_bench.importers.errors import SUPPORTED, ImportFileError
from tsa_bench.importers.table import SourceTable


def sniff(path: Path) -> str:
    """"text", "xlsx", "mat5", "mat73" or "tdms"; ImportFileError for anything else."""
    try:
        check_regular_file(path, "data file")
        with open(path, "rb") as f:
            head = f.read(65536)
    except DocumentError as exc:
        raise ImportFileError(str(exc)) from None
    except OSError as exc:
        raise ImportFileError(f"{path}: cannot read ({exc.strerror or exc})") from None
    suffix = path.suffix.lower()
    if head.startswith(b"MATLAB 7.3 MAT-file"):
        return "mat73"
    if head.startswith(b"MATLAB 5.0 MAT-file") or (suffix == ".mat" and head[:4] != b"\x89HDF" and b"\0" in head[:128]
                                                   and head[:6].isascii() and head[:6].isalpha()):
        return "mat5"
    if head.startswith(b"TDSm"):
        return "tdms"
    if head.startswith(b"PK\x03\x04"):
        if b"xl/" in head or suffix in (".xlsx", ".xlsm"):
            return "xlsx"
        looks = "a zip archive (not an Excel workbook)"
    elif head.startswith(b"\xd0\xcf\x11\xe0"):
        looks = "a legacy Excel .xls (or other OLE2) file; save it as .xlsx or CSV"
    elif head.startswith(b"\x89HDF\r\n\x1a\n"):
        looks = ("an HDF5 file (a tsa-bench run file needs no import; a MATLAB v7.3 file starts with its "
                 "'MATLAB 7.3 MAT-file' header)")
    elif b"\0" not in head and suffix == ".m":
        looks = ("MATLAB source code (a script or function), not data: run it in MATLAB and save the workspace "
                 "as a .mat file (save('run.mat')), then import that")
    elif b"\0" not in head:
        return "text"
    else:
        looks = f"binary data of no known format (first bytes {head[:8].hex(' ')})"
    raise ImportFileError(f"{path}: looks like {looks}; supported formats: {SUPPORTED}")


def read_source(path: Path, options: Any) -> SourceTable:
    """Read ``path`` with the reader its format needs; options as :class:`.pipeline.ImportOptions`."""
    fmt = sniff(path)
    if fmt == "text":
        from tsa_bench.importers.text import read_text
        return read_text(path, options.no_header, options.delimiter, options.decimal)
    if fmt == "xlsx":
        from tsa_bench.importers.spreadsheet import read_xlsx
        return read_xlsx(path, options.sheet, options.no_header)
    if fmt in ("mat5", "mat73"):
        from tsa_bench.importers.matlab import read_mat
        return read_mat(path, options.var, fmt, list((options.mapping or {}).values()))
    from tsa_bench.importers.tdms import read_tdms
    return read_tdms(path, options.group)
