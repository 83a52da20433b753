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

The data rows are parsed by pyarrow's CSV reader (blank-separated ones by numpy's
loadtxt); a file it cannot take as it is - a cell that is not a number, a row of another
width, comment or blank lines among the data, quotes spanning lines, a text that is not
UTF-8 - is read again line by line (:func:`_careful`), which names every problem with its
line, so messages are the same whichever path read the file.
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
from tsa_bench.store.budget import check_budget

MAX_TEXT_BYTES = 1 << 30
#: Memory per byte of a text table while it is split into cells and numbers (measured: 6-8).
TEXT_FACTOR = 10
DELIMITERS = ("\t", ";", ",", "|", " ")
_NAMES = {"\t": "tab", ";": "';'", ",": "','", "|": "'|'", " ": "blanks"}
_DECIMAL_COMMA = re.compile(r"^[+-]?\d+,\d+(?:[eE][+-]?\d+)?$")
_CHUNK = 200_000
_COMMENT_LINE = re.compile(rb"(?:^|\n)[ \t]*(?:#|%|//)")


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


def _raw(path: Path) -> bytes:
    try:
        size = path.stat().st_size
    except OSError:
        size = 0   # read_bytes_file says what is wrong
    check_budget(size * TEXT_FACTOR, str(path), "its text")
    try:
        raw = read_bytes_file(path, "data file", MAX_TEXT_BYTES)
    except DocumentError as exc:
        raise ImportFileError(str(exc)) from None
    return raw[3:] if raw.startswith(b"\xef\xbb\xbf") else raw


def decode(raw: bytes) -> tuple[str, list[str], bool]:
    """(text, notes, is UTF-8) of a text file's bytes: UTF-8, else Windows-1252 (said so)."""
    try:
        return raw.decode("utf-8"), [], True
    except UnicodeDecodeError as exc:
        return raw.decode("cp1252", errors="replace"), [
            f"not UTF-8 (byte 0x{raw[exc.start]:02X} at offset {exc.start}): read as Windows-1252"], False


def _head(raw: bytes, limit: int) -> str:
    """The start of an ASCII file, long enough to hold ``limit`` content lines (or all of it)."""
    size = 1 << 16
    while True:
        text = raw[:size].decode("ascii")
        lines = text.split("\n")
        if size >= len(raw) or sum(1 for ln in lines[:-1] if ln.strip() and not is_comment(ln)) >= limit:
            return text if size >= len(raw) else text[:len(text) - len(lines[-1])]
        size *= 4


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


def _comment_lines(raw: bytes, start: int) -> bool:
    """Whether a line from byte ``start`` on is a comment (``#``, ``%``, ``//``, maybe indented); fast
    byte searches first, the regular expression only for a file with indented lines."""
    if raw.startswith((b"#", b"%", b"//"), start) or any(raw.find(s, start) >= 0 for s in (b"\n#", b"\n%", b"\n//")):
        return True
    indented = raw.find(b"\n ", start) >= 0 or raw.find(b"\n\t", start) >= 0 or raw.startswith((b" ", b"\t"), start)
    return indented and _COMMENT_LINE.search(raw, start) is not None


def _arrow(raw: bytes, start: int, delim: str, decimal_comma: bool, width: int,
           cols: list[int]) -> list[np.ndarray] | None:
    """The numeric columns ``cols`` of the data lines (``raw`` from byte ``start``) parsed by pyarrow's CSV
    reader, or None when the
    text needs the careful path (module contract): pyarrow refused it (a comment line among the data
    fails a number column's conversion), or it holds blank lines, which pyarrow reads as rows of empty
    cells where the careful path skips them."""
    import pyarrow as pa
    import pyarrow.csv as pc

    body = memoryview(raw)[start:]
    if not cols or not body or bytes(body[:1 << 16]).isspace() and bytes(body).isspace():
        return None
    if len(cols) < width and _comment_lines(raw, start):
        return None  # a comment line fails a number column's conversion, but not when only others are read
    names = [f"c{i}" for i in range(width)]
    try:
        table = pc.read_csv(
            pa.py_buffer(body),
            read_options=pc.ReadOptions(column_names=names, use_threads=False, block_size=len(body) + 1),
            parse_options=pc.ParseOptions(delimiter=delim, quote_char='"', double_quote=True,
                                          newlines_in_values=False, ignore_empty_lines=False),
            convert_options=pc.ConvertOptions(column_types={names[i]: pa.float64() for i in cols},
                                              include_columns=[names[i] for i in cols], null_values=[""],
                                              strings_can_be_null=True, quoted_strings_can_be_null=True,
                                              decimal_point="," if decimal_comma else "."))
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError, pa.ArrowTypeError, ValueError):
        return None   # the careful path names what pyarrow refused
    out = []
    for name in [names[i] for i in cols]:
        out.append(_floats(table.column(name)))
        table = table.drop_columns([name])  # each column's Arrow buffers go as soon as numpy holds them
    if out and all(np.isnan(a).any() for a in out) and np.logical_and.reduce([np.isnan(a) for a in out]).any():
        return None  # a row empty in every column: a blank line, which the careful path skips with its number
    return out


def _floats(col: "pa.ChunkedArray") -> np.ndarray:  # noqa: F821
    """A float64 Arrow column as numpy, nulls as NaN, read from its buffers (Array.to_numpy would import pandas)."""
    if col.num_chunks == 1 and col.null_count == 0:   # one block (the whole body): numpy views its buffer
        ch = col.chunk(0)
        return np.frombuffer(ch.buffers()[1], np.float64, count=len(ch), offset=ch.offset * 8)
    out = np.empty(len(col), np.float64)
    pos = 0
    for ch in col.chunks:
        k = len(ch)
        validity, values = ch.buffers()[:2]
        out[pos:pos + k] = np.frombuffer(values, np.float64, count=k, offset=ch.offset * 8)
        if ch.null_count:
            bits = np.unpackbits(np.frombuffer(validity, np.uint8), bitorder="little")[ch.offset:ch.offset + k]
            out[pos:pos + k][bits == 0] = np.nan
        pos += k
    return out


def _blank_separated(data: str, width: int) -> np.ndarray | None:
    """Blank-separated data lines parsed in one C pass (numpy's loadtxt), or None for the careful path
    (comment, blank or indented lines, rows of another width, a cell that is not a number)."""
    body = data.rstrip("\n")
    if not body.strip() or body[:1] in "#%/ \t" or "\n\n" in body or any(
            f"\n{c}" in body for c in ("#", "%", "//", " ", "\t")):
        return None
    n_lines = body.count("\n") + 1
    try:
        out = np.loadtxt(io.StringIO(body), delimiter=None, ndmin=2, comments=None, dtype=np.float64, quotechar=None)
    except ValueError:
        return None
    return out if len(out) == n_lines and out.shape[1] == width else None


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
    raw = _raw(path)
    if b"\r" in raw and raw.count(b"\r") != raw.count(b"\r\n"):  # bare CRs end lines too (old Mac files)
        raw = raw.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    if raw.isascii():  # the common case: only the head is decoded; the data rows go to pyarrow as bytes
        text, notes, utf8 = _head(raw, 40), [], True
    else:
        text, notes, utf8 = decode(raw)
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
    at = offsets[start] if start < len(offsets) else len(text)
    # columns whose first cells are numbers take the fast path; the others keep their first bad cells
    probe = [c for _, c in records[first:] if len(c) == width]
    numeric = [i for i in range(width) if all(_is_number(c[i], decimal_comma) or not c[i].strip() for c in probe)]
    fast: list[np.ndarray] | None = None
    if delim == " ":
        if raw.isascii():
            text, _, _ = decode(raw)
        data = text[at:]
        block = _blank_separated(data, width) if len(numeric) == width else None
        fast = [block[:, i] for i in range(width)] if block is not None else None
    elif utf8:
        fast = _arrow(raw, len(text[:at].encode("utf-8")), delim, decimal_comma, width, numeric)
    if fast is not None:
        n = len(fast[0])
        columns = []
        for i in range(width):
            if i in numeric:
                columns.append(Column(names[i], fast[numeric.index(i)]))
            else:
                vals, bad, n_bad = numbers([c[i] for c in probe])
                columns.append(Column(names[i], np.full(n, np.nan), bad, max(n_bad, 1)))
        return SourceTable(path, "text", columns, range(start + 1, start + 1 + n), header_line,
                           header is not None, notes)
    if raw.isascii() and delim != " ":
        text, _, _ = decode(raw)
    del raw
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
        head, offsets = _lines(text, 40)
        at = offsets[start] if start < len(offsets) else len(text)
    return _careful(path, text[at:].splitlines(), start, split, width, names, header is not None, header_line,
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
