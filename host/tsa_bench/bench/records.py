"""Calibration records kept in a bench file (``calibrations:``), newest last.

Contract: ``tsa-bench calibrate`` appends one record per calibration and writes the
result into ``position_sensor`` or ``resistance_sensor``; the records are the history
that says where those numbers came from. Each record is a mapping::

    - quantity: position                      # or resistance
      date: "2025-03-01T10:12:00+01:00"       # ISO 8601, when it was measured
      device: "firmware 0.1.0 on /dev/ttyACM0"   # optional text
      note: "..."                             # optional text
      points:                                 # two or more
        - {counts: 11200.4, length_mm: 240.0, fit_mm: 240.02, residual_mm: -0.02}
      result: {mm_per_count: 0.0105, offset_mm: 121.9}
      rms_residual_mm: 0.03

(resistance: ``resistance_ohm``, ``fit_ohm``, ``residual_ohm`` per point, ``result``
``{gain: ..., offset_ohm: ...}`` and ``rms_residual_ohm``). :func:`check_records`
checks every key and value and raises one ``BenchConfigError`` line
``file:line:col: calibrations[i].key: what``.
"""

from __future__ import annotations

import datetime as dt
import math
from typing import Any

from tsa_bench.userfiles import YamlDocument

#: quantity -> (point keys, result keys, rms key)
QUANTITIES: dict[str, tuple[tuple[str, ...], tuple[str, ...], str]] = {
    "position": (("counts", "length_mm", "fit_mm", "residual_mm"), ("mm_per_count", "offset_mm"),
                 "rms_residual_mm"),
    "resistance": (("counts", "resistance_ohm", "fit_ohm", "residual_ohm"), ("gain", "offset_ohm"),
                   "rms_residual_ohm"),
}
MAX_RECORDS = 10_000
MAX_POINTS = 10_000


def _error(doc: YamlDocument, path: tuple[str | int, ...], message: str):
    from tsa_bench.bench.errors import BenchConfigError

    shown = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in path).lstrip(".")
    return BenchConfigError(f"{doc.where(*path)}: {shown}: {message}")


def _number(doc: YamlDocument, value: Any, path: tuple[str | int, ...]) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        raise _error(doc, path, f"must be a finite number, got {value!r}")


def check_records(doc: YamlDocument, records: Any) -> None:
    """Validate the ``calibrations`` list (module contract); None means no records."""
    if records is None:
        return
    top = ("calibrations",)
    if not isinstance(records, list):
        raise _error(doc, top, f"must be a list of calibration records, got {type(records).__name__}")
    if len(records) > MAX_RECORDS:
        raise _error(doc, top, f"{len(records)} records, at most {MAX_RECORDS}")
    for i, rec in enumerate(records):
        at = (*top, i)
        if not isinstance(rec, dict):
            raise _error(doc, at, "each record is a mapping (quantity, date, points, result, ...)")
        quantity = rec.get("quantity")
        if quantity not in QUANTITIES:
            raise _error(doc, (*at, "quantity"), f"must be one of {', '.join(QUANTITIES)}, got {quantity!r}")
        point_keys, result_keys, rms_key = QUANTITIES[quantity]
        allowed = ("quantity", "date", "device", "note", "points", "result", rms_key)
        for key in rec:
            if key not in allowed:
                raise _error(doc, (*at, key), f"unknown key (allowed: {', '.join(allowed)})")
        for key in ("date", "points", "result"):
            if key not in rec:
                raise _error(doc, at, f"missing required key '{key}'")
        try:
            dt.datetime.fromisoformat(str(rec["date"]))
        except ValueError:
            raise _error(doc, (*at, "date"), f"must be an ISO 8601 date and time, got {rec['date']!r}") from None
        for key in ("device", "note"):
            if key in rec and not isinstance(rec[key], str):
                raise _error(doc, (*at, key), f"must be text, got {rec[key]!r}")
        points = rec["points"]
        if not isinstance(points, list) or not 2 <= len(points) <= MAX_POINTS:
            raise _error(doc, (*at, "points"), f"must be a list of 2..{MAX_POINTS} points")
        for j, point in enumerate(points):
            if not isinstance(point, dict):
                raise _error(doc, (*at, "points", j), f"each point is a mapping of {', '.join(point_keys)}")
            for key in point:
                if key not in point_keys:
                    raise _error(doc, (*at, "points", j, key), f"unknown key (allowed: {', '.join(point_keys)})")
            for key in point_keys[:2]:
                if key not in point:
                    raise _error(doc, (*at, "points", j), f"missing required key '{key}'")
            for key, value in point.items():
                _number(doc, value, (*at, "points", j, key))
        result = rec["result"]
        if not isinstance(result, dict) or set(result) != set(result_keys):
            raise _error(doc, (*at, "result"), f"must be a mapping of exactly {', '.join(result_keys)}")
        for key, value in result.items():
            _number(doc, value, (*at, "result", key))
        if rms_key in rec:
            _number(doc, rec[rms_key], (*at, rms_key))
