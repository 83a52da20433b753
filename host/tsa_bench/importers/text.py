"""Delimited text: CSV, TSV, semicolon or whitespace separated, with or without a header.

Contract of :func:`read_text`:

* the text is UTF-8 (a BOM is dropped); a file that is not is read as Windows-1252 and
  the summary says so;
* blank lines and comment lines (starting with ``#``, ``%`` or ``//``) are skipped
  anywhere; the delimiter (tab, ``;``, ``,``, ``|`` or runs of blanks) is the one that
  splits the first 40 content lines into the same number (>= 2) of cells most often,
  unless given;
* lines before the first line with that many cells are a preamble (a logger's date,
  operator, ...) and skipped, said so in the notes;
* the first line of that width is the header, unless ``no_header`` or unless every cell
  of it is a number (then the file has no header and columns are named by position);
* a decimal comma (``1,5``) is recognised when the delimiter is not a comma, or forced
  with ``decimal=","``;
* every data row must have as many cells as the header (up to 20 rows named at once).
"""

from __future__ import annotations

import csv
import io
import re
from collections import Counter
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from tsa_bench.userfiles import DocumentError
from tsa_bench.userfiles.files import read_bytes_file
from tsa_bench.importers.errors import ImportFileError
from tsa_bench.importers.table import Column, SourceTable, numbers

MAX_TEXT_BYTES = 1 << 30
DELIMITERS = ("\t", ";", ",", "|", " ")
_NAMES = {"\t": "tab", ";": "';'", ",": "','", "|": "'|'", " ": "blanks"}
_DECIMAL_COMMA = re.compile(r"^[+-]?\d+,\d+(?:[eE][+-]?\d+)?$")
_CHUNK = 200_000


def is_comment(line: str) -> bool:
    s = line.lstrip()
    return s.startswith(("#", "%", "//"))


def splitter(delim: str) -> Callable[[list[str]], Iterable[list[str]]]:
    """A function splitting a list of lines into cells (csv quoting for real delimiters)."""
    if delim == " ":
        return lambda lines: (ln.split() for ln in lines)
    return lambda lines: csv.reader(lines, delimiter=delim)


def _is_number(cell: str, decimal_comma: bool) -> bool:
    c = cell.strip().replace(",", ".") if decimal_comma else cell.strip()
    try:
        float(c)
    except ValueError:
        return False
    return True


def choose_delimiter(sample: list[str]) -> str:
    """The delimiter giving the most sample lines the same width >= 2 (see module contract)."""
    best, best_score = ",", (0, 0)
    for d in DELIMITERS:
        try:
            widths = [len(cells) for cells in splitter(d)(sample)]
        except csv.Error:
            continue
        width, agree = Counter(widths).most_common(1)[0] if widths else (0, 0)
        if width >= 2 and (agree, 0) > best_score:
            best, best_score = d, (agree, 0)
    return best


def decode(path: Path) -> tuple[str, list[str]]:
    """(text, notes) of a text file: UTF-8, else Windows-1252 (said so)."""
    try:
        raw = read_bytes_file(path, "data file", MAX_TEXT_BYTES)
    except DocumentError as exc:
        raise ImportFileError(str(exc)) from None
    try:
        return raw.decode("utf-8-sig"), []
    except UnicodeDecodeError as exc:
        return raw.decode("cp1252", errors="replace"), [
            f"not UTF-8 (byte 0x{raw[exc.start]:02X} at offset {exc.start}): read as Windows-1252"]


def layout(records: list[tuple[int, list[str]]], no_header: bool, decimal_comma: bool,
           path: Path) -> tuple[int, list[str] | None, int, list[str]]:
    """(index into ``records`` of the first data record, header cells or None, width, notes)
    from the first content records (module contract: preamble, header, headerless)."""
    if not records:
        raise ImportFileError(f"{path}: no header line (the file is empty or only comments)")
    width = Counter(len(c) for _, c in records).most_common(1)[0][0]
    first = next(k for k, (_, c) in enumerate(records) if len(c) == width)
    notes = []
    if first:
        a, b = records[0][0], records[first - 1][0]
        notes.append(f"skipped {first} preamble line{'s' if first > 1 else ''} ({a}-{b}: "
                     f"{' '.join(records[0][1])[:40]!r}...)")
    cells = records[first][1]
    if no_header:
        return first, None, width, notes
    if all(_is_number(c, decimal_comma) for c in cells):
        notes.append(f"line {records[first][0]} is all numbers: the file has no header, columns are named "
                     "by position (1, 2, ...)")
        return first, None, width, notes
    return first + 1, [c.strip() for c in cells], width, notes


def _fast(data: str, delim: str, decimal_comma: bool, width: int, cols: list[int]) -> np.ndarray | None:
    """The numeric columns ``cols`` of the data lines parsed in one C pass (numpy's loadtxt), or None
    when the text needs the careful path: quotes, comment or blank lines, rows of another width, a
    cell that is not a number (the careful path then names each one)."""
    body = data.rstrip("\n")
    if not cols or '"' in body or "\n\n" in body or body[:1] in "#%/ \t" or any(
            f"\n{c}" in body for c in ("#", "%", "//", " ", "\t")):
        return None  # quotes, blank, comment or indented lines: the careful path
    n_lines = data.count("\n") + (0 if data.endswith("\n") else 1)
    if delim == " " and len(cols) != width:
        return None  # blank-separated: loadtxt checks every row's width only when it reads every column
    if delim != " ":
        if data.count(delim) != n_lines * (width - 1):
            return None
        for _ in range(2):  # empty cells are NaN: ",," -> ",nan,", also at the start and end of a line
            if delim + delim in data:
                data = data.replace(delim + delim, f"{delim}nan{delim}")
        if "\n" + delim in data:
            data = data.replace("\n" + delim, f"\nnan{delim}")
        if delim + "\n" in data:
            data = data.replace(delim + "\n", f"{delim}nan\n")
        if data.startswith(delim):
            data = "nan" + data
        if data.endswith(delim):
            data += "nan"
    if decimal_comma:
        data = data.replace(",", ".")
    try:
        out = np.loadtxt(io.StringIO(data), delimiter=None if delim == " " else delim,
                         usecols=None if delim == " " else cols, ndmin=2,
                         comments=None, dtype=np.float64, quotechar=None)
    except ValueError:
        return None
    return out if len(out) == n_lines else None


def _lines(text: str, limit: int) -> tuple[list[str], list[int]]:
    """The first lines of ``text`` up to ``limit`` content lines, and the offset where each starts."""
    lines, starts, pos, found = [], [], 0, 0
    while pos < len(text) and found < limit:
        j = text.find("\n", pos)
        j = len(text) if j < 0 else j
        line = text[pos:j].rstrip("\r")
        lines.append(line)
        starts.append(pos)
        pos = j + 1
        if line.strip() and not is_comment(line):
            found += 1
    starts.append(min(pos, len(text)))
    return lines, starts


def read_text(path: Path, no_header: bool = False, delimiter: str | None = None,
              decimal: str | None = None) -> SourceTable:
    """Read a delimited text file (module contract) into a :class:`SourceTable`."""
    text, notes = decode(path)
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    head, offsets = _lines(text, 40)
    content = [i for i, line in enumerate(head) if line.strip() and not is_comment(line)]
    sample = [head[i] for i in content]
    delim = delimiter if delimiter is not None else choose_delimiter(sample)
    if delim in ("tab", "\\t"):
        delim = "\t"
    if delim in ("space", "whitespace"):
        delim = " "
    split = splitter(delim)
    try:
        records = list(zip([i + 1 for i in content], split(sample)))
    except csv.Error as exc:
        raise ImportFileError(f"{path}: not valid delimited text ({exc})") from None
    if decimal is None:
        decimal_comma = delim != "," and any(_DECIMAL_COMMA.match(c.strip()) for _, cells in records for c in cells)
    else:
        decimal_comma = decimal == ","
    first, header, width, more = layout(records, no_header, decimal_comma, path)
    notes += more
    notes.append(f"delimiter {_NAMES.get(delim, repr(delim))}" + (", decimal comma" if decimal_comma else ""))
    start = records[first][0] - 1 if first < len(records) else len(head)
    header_line = records[first - 1][0] if header is not None else None
    names = header if header is not None else [""] * width
    data = text[offsets[start]:] if start < len(offsets) else ""
    del text
    # columns whose first cells are numbers take the fast path; the others keep their first bad cells
    probe = [c for _, c in records[first:] if len(c) == width]
    numeric = [i for i in range(width) if all(_is_number(c[i], decimal_comma) or not c[i].strip() for c in probe)]
    fast = _fast(data, delim, decimal_comma, width, numeric) if data.strip() else None
    if fast is not None:
        n = len(fast)
        columns = []
        for i in range(width):
            if i in numeric:
                columns.append(Column(names[i], fast[:, numeric.index(i)]))
            else:
                vals, bad, n_bad = numbers([c[i] for c in probe])
                columns.append(Column(names[i], np.full(n, np.nan), bad, max(n_bad, 1)))
        return SourceTable(path, "text", columns, np.arange(start + 1, start + 1 + n), header_line,
                           header is not None, notes)
    return _careful(path, data.splitlines(), start, split, width, names, header is not None, header_line,
                    decimal_comma, notes)


def _careful(path: Path, lines: list[str], start: int, split: Callable, width: int, names: list[str],
             has_header: bool, header_line: int | None, decimal_comma: bool, notes: list[str]) -> SourceTable:
    """Line by line (csv module), naming every row of the wrong width and keeping bad cells per column."""
    parts: list[list[np.ndarray]] = [[] for _ in range(width)]
    bad: list[list[tuple[int, str]]] = [[] for _ in range(width)]
    n_bad = [0] * width
    row_lines: list[np.ndarray] = []
    errors: list[str] = []
    n_done = 0
    for c0 in range(0, len(lines), _CHUNK):
        chunk = lines[c0:c0 + _CHUNK]
        keep = [k for k, ln in enumerate(chunk) if ln.strip() and not is_comment(ln)]
        chunk = [chunk[k] for k in keep]
        try:
            rows = list(split(chunk))
        except csv.Error as exc:
            raise ImportFileError(f"{path}: not valid delimited text after line {start + c0}: {exc}") from None
        if len(rows) != len(chunk):
            raise ImportFileError(f"{path}:{start + c0 + 1}: a quoted cell spans lines; data rows must be one line each")
        nums = np.asarray(keep, int) + start + c0 + 1
        good = [k for k, r in enumerate(rows) if len(r) == width]
        if len(good) != len(rows):
            what = "the header has" if has_header else "the first data line has"
            for k, r in enumerate(rows):
                if len(r) != width and len(errors) < 20:
                    errors.append(f"{path}:{int(nums[k])}: {len(r)} cells, {what} {width}")
            rows = [rows[k] for k in good]
            nums = nums[good]
        if errors:
            continue
        row_lines.append(nums)
        cols = list(zip(*rows)) if rows else [()] * width
        for i in range(width):
            vals, b, nb = numbers(list(cols[i]), decimal_comma)
            parts[i].append(vals)
            if nb:
                n_bad[i] += nb
                bad[i].extend((n_done + k, cell) for k, cell in b[:20 - len(bad[i])])
        n_done += len(rows)
    if errors:
        raise ImportFileError("\n".join(errors) + (" (stopped after the first errors)" if len(errors) >= 20 else ""))
    columns = [Column(names[i], np.concatenate(parts[i]) if parts[i] else np.empty(0), bad[i], n_bad[i])
               for i in range(width)]
    return SourceTable(path, "text", columns, np.concatenate(row_lines) if row_lines else np.empty(0, int),
                       header_line, has_header, notes)
