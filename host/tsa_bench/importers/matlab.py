"""MATLAB .mat files: v5 through scipy.io, v7.3 (HDF5) through h5py.

Contract of :func:`read_mat`: the variable ``var`` (or, without it, the file's only
matrix or struct, or all its vectors of one length, or the vectors ``--map`` names) becomes
the table:

* a struct of vectors: one column per field, named by the field;
* a matrix: one column per column (the shorter side is the columns), named by position;
* vectors: one column each, named by the variable.

Vectors (or struct fields) of different lengths: the ones ``--map`` names (``wanted``) are
taken, and must then be of one length; the others are left out, said so. Without
``--map`` a struct keeps its fields of the longest length and loose vectors need ``--var``
or ``--map``.

v7.3 files store arrays transposed (MATLAB is column-major); they are turned back. Rows
are numbered from 1 in messages (``file:row 12``).
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from tsa_bench.importers.errors import SUPPORTED, ImportFileError
from tsa_bench.importers.table import Column, SourceTable
from tsa_bench.store.budget import check_budget, memory_budget


def _v5_unpacked_bytes(path: Path, limit: float) -> int:
    """Bytes of a v5 file's variables once unpacked, counted by streaming through them (a
    compressed variable is inflated piece by piece and dropped), stopping past ``limit``:
    a few kilobytes can declare or inflate to gigabytes."""
    total = 0
    with open(path, "rb") as f:
        head = f.read(128)
        order = "<" if head[126:128] == b"IM" else ">"
        while total <= limit:
            tag = f.read(8)
            if len(tag) < 8:
                break
            kind, size = struct.unpack(order + "II", tag)
            if kind >> 16:   # a small element packed in its tag
                total += 4
                continue
            if kind != 15:   # stored as it is
                total += size
                f.seek(size + (-size % 8), 1)
                continue
            inflate, left = zlib.decompressobj(), size
            while left and total <= limit:
                piece = f.read(min(left, 1 << 16))
                if not piece:
                    break
                left -= len(piece)
                data = piece
                while data and total <= limit:
                    total += len(inflate.decompress(data, 1 << 20))
                    data = inflate.unconsumed_tail
            f.seek(left, 1)
    return total


def _v5(path: Path) -> dict[str, Any]:
    import scipy.io

    limit = memory_budget() / 2
    try:
        unpacked = _v5_unpacked_bytes(path, limit)
    except (OSError, struct.error, zlib.error):
        unpacked = 0   # damaged: loadmat below says why
    check_budget(unpacked * 2.0, str(path), "its variables")   # the values, and the float copy of the table
    try:
        raw = scipy.io.loadmat(path, simplify_cells=True)
    except MemoryError:
        raise
    except Exception as exc:  # scipy raises ValueError, TypeError, ... on damaged files
        raise ImportFileError(f"{path}: looks like a MATLAB v5 .mat file but cannot be read "
                              f"({type(exc).__name__}: {exc}); supported formats: {SUPPORTED}") from None
    return {k: v for k, v in raw.items() if not k.startswith("__")}


def _h5(node: Any) -> Any:
    import h5py

    if isinstance(node, h5py.Group):
        return {k: _h5(v) for k, v in node.items() if not k.startswith("#")}
    a = node[()]
    return np.asarray(a).T if getattr(a, "ndim", 0) else a


def _v73(path: Path) -> dict[str, Any]:
    import h5py

    from tsa_bench.store.probe import check_hdf5_terminates

    why = check_hdf5_terminates(path)
    if why:
        raise ImportFileError(f"{path}: {why}")
    try:
        with h5py.File(path, "r") as f:
            declared = [0.0]

            def add(_name: str, obj: Any) -> None:
                if isinstance(obj, h5py.Dataset) and obj.shape is not None:
                    declared[0] += float(np.prod(obj.shape, dtype=float)) * (obj.dtype.itemsize + 8)

            f.visititems(add)
            check_budget(declared[0], str(path), "its variables")
            return {k: _h5(v) for k, v in f.items() if not k.startswith("#")}
    except OSError as exc:
        raise ImportFileError(f"{path}: looks like a MATLAB v7.3 .mat file but cannot be read ({exc}); "
                              f"supported formats: {SUPPORTED}") from None


def _numeric(v: Any) -> np.ndarray | None:
    a = np.asarray(v)
    if a.dtype.kind not in "fiub" or a.size < 1:
        return None
    return np.squeeze(a).astype(float)


def _describe(d: dict[str, Any]) -> str:
    parts = []
    for k, v in d.items():
        a = _numeric(v)
        parts.append(f"{k} (struct)" if isinstance(v, dict) else f"{k} {'x'.join(map(str, np.shape(v)))}"
                     if a is not None else f"{k} (not numeric)")
    return ", ".join(parts) or "none"


def _chosen(path: Path, what: str, vectors: dict[str, np.ndarray], wanted: list[str]) -> dict[str, np.ndarray]:
    """The vectors ``wanted`` names (exactly or in another case); they must be of one length."""
    low = {k.lower(): k for k in vectors}
    names = [w if w in vectors else low.get(w.lower()) for w in wanted]
    picked = {k: vectors[k] for k in names if k is not None}
    if not picked:
        return {}
    lengths = {len(a) for a in picked.values()}
    if len(lengths) > 1:
        raise ImportFileError(f"{path}: the {what} --map names are of different lengths "
                              f"({', '.join(f'{k} {len(a)}' for k, a in picked.items())}); map vectors of one length")
    return picked


def _columns(path: Path, name: str, v: Any, wanted: list[str]) -> tuple[list[Column], bool, list[str]]:
    if isinstance(v, dict):
        cols = [(k, _numeric(x)) for k, x in v.items()]
        cols = [(k, a) for k, a in cols if a is not None and a.ndim == 1]
        if not cols:
            raise ImportFileError(f"{path}: struct '{name}' has no numeric vector fields ({_describe(v)})")
        picked = _chosen(path, f"fields of struct '{name}'", dict(cols), wanted)
        n = len(next(iter(picked.values()))) if picked else max(len(a) for _, a in cols)
        kept = [Column(k, a) for k, a in cols if len(a) == n]
        notes = [f"struct '{name}': fields {', '.join(c.name for c in kept)}"]
        dropped = [k for k, a in cols if len(a) != n]
        if dropped:
            notes.append(f"fields of another length left out: {', '.join(dropped)}")
        return kept, True, notes
    a = _numeric(v)
    if a is None:
        raise ImportFileError(f"{path}: variable '{name}' is not numeric")
    if a.ndim == 1:
        return [Column(name, a)], True, [f"vector '{name}'"]
    if a.ndim != 2:
        raise ImportFileError(f"{path}: variable '{name}' has {a.ndim} dimensions; give a matrix, vectors or a struct")
    if a.shape[0] < a.shape[1]:
        a = a.T
    return [Column("", a[:, i].copy()) for i in range(a.shape[1])], False, [
        f"matrix '{name}' {a.shape[0]}x{a.shape[1]}: columns named by position (--map t=1,...)"]


def read_mat(path: Path, var: str | None, fmt: str, wanted: list[str] | None = None) -> SourceTable:
    """Read a .mat file (module contract) into a :class:`SourceTable`; ``wanted``: the names ``--map`` gives."""
    wanted = wanted or []
    d = _v5(path) if fmt == "mat5" else _v73(path)
    version = "v5" if fmt == "mat5" else "v7.3"
    if var is not None:
        if var not in d:
            raise ImportFileError(f"{path}: no variable '{var}' (variables: {_describe(d)})")
        cols, named, notes = _columns(path, var, d[var], wanted)
    else:
        structs = [k for k, v in d.items() if isinstance(v, dict)]
        arrays = {k: a for k, v in d.items() if not isinstance(v, dict) for a in [_numeric(v)] if a is not None}
        matrices = [k for k, a in arrays.items() if a.ndim == 2]
        vectors = {k: a for k, a in arrays.items() if a.ndim == 1}
        if len(structs) + len(matrices) == 1 and not vectors:
            cols, named, notes = _columns(path, (structs + matrices)[0], d[(structs + matrices)[0]], wanted)
        elif vectors and not structs and not matrices and len({len(a) for a in vectors.values()}) == 1:
            cols, named, notes = [Column(k, a) for k, a in vectors.items()], True, [f"vectors {', '.join(vectors)}"]
        elif picked := _chosen(path, "vectors", vectors, wanted):
            n = len(next(iter(picked.values())))
            same = {k: a for k, a in vectors.items() if len(a) == n}  # unmapped ones of that length are picked up
            other = [f"{k} ({len(a)})" for k, a in vectors.items() if len(a) != n]
            cols, named = [Column(k, a) for k, a in same.items()], True
            notes = [f"vectors {', '.join(same)} ({n} rows, chosen by --map)"] + (
                [f"vectors of another length left out: {', '.join(other)}"] if other else [])
        else:
            raise ImportFileError(f"{path}: choose the variable with --var, or the vectors with --map "
                                  f"(variables: {_describe(d)})")
    n = len(cols[0].values)
    return SourceTable(path, f"MATLAB {version}", cols, np.arange(1, n + 1), None, named, notes, row_prefix="row ")
