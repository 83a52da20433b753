"""Logger clocks as they come: rows out of time order, repeated times, the sample rate found.

Contract of :func:`order_rows` (``t`` in s, one value per source row):

* ``mode`` "error": any row whose time is not after every earlier row's raises
  :class:`ImportFileError` naming the first such line and how many rows are affected;
* "sort": rows are sorted by time (stable) and rows repeating an earlier time dropped
  (the first kept);
* "drop": rows whose time is not after every earlier row's are dropped.

It returns the row indices to keep, in order, and a record of what was done (stored in
the run's metadata). :func:`sample_rate` gives the median rate and the interval jitter.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from tsa_bench.importers.errors import ImportFileError

MODES = ("error", "sort", "drop")


def _rows(n: int) -> str:
    return f"{n} row{'' if n == 1 else 's'}"


def _late(t: np.ndarray) -> np.ndarray:
    """Mask of rows whose time is not after the running maximum of the rows before."""
    late = np.zeros(len(t), bool)
    if len(t) > 1:
        late[1:] = t[1:] <= np.maximum.accumulate(t)[:-1]
    return late


def order_rows(t: np.ndarray, mode: str, line: Callable[[int], str], column: str) -> tuple[np.ndarray, dict[str, Any]]:
    """(indices of the rows kept, record of what was done); see the module contract."""
    late = _late(t)
    n_late = int(late.sum())
    if not n_late:
        return np.arange(len(t)), {"mode": mode, "rows_affected": 0}
    k = int(np.flatnonzero(late)[0])
    first = {"first_line": line(k)}
    if mode == "error":
        raise ImportFileError(
            f"{line(k)}: column {column} (t): time {t[k]:g} s is not after {t[k - 1]:g} s on line "
            f"{line(k - 1).rsplit(':', 1)[-1]}; {n_late} row{'s are' if n_late > 1 else ' is'} out of order or "
            "repeated; time must strictly increase (--time-order sort or drop imports them anyway)")
    if mode == "drop":
        keep = np.flatnonzero(~late)
        return keep, {"mode": "drop", "rows_affected": n_late, "rows_dropped": n_late, **first,
                      "said": f"dropped {_rows(n_late)} whose time was not after the rows before "
                              f"(first at {line(k)})"}
    order = np.argsort(t, kind="stable")
    ts = t[order]
    dup = np.zeros(len(ts), bool)
    dup[1:] = ts[1:] == ts[:-1]
    n_moved = int((order != np.arange(len(t))).sum())
    keep = order[~dup]
    n_dup = int(dup.sum())
    return keep, {"mode": "sort", "rows_affected": n_late, "rows_moved": n_moved, "rows_dropped": n_dup, **first,
                  "said": f"sorted by time: {_rows(n_moved)} moved, {_rows(n_dup)} repeating an earlier time dropped "
                          f"(first out of order at {line(k)})"}


def sample_rate(t: np.ndarray) -> dict[str, float] | None:
    """Median sample rate (Hz), median interval and interval jitter (rms and largest, s); None for < 2 rows."""
    if len(t) < 2:
        return None
    dt = np.diff(t)
    med = float(np.median(dt))
    return {"rate_hz": 1.0 / med if med > 0 else float("inf"), "interval_s": med,
            "jitter_rms_s": float(np.sqrt(np.mean((dt - med) ** 2))), "largest_interval_s": float(dt.max())}
