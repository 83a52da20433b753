"""The `tsa-bench diagnose` report: the text (diagnose_text.py), figures
(diagnose_figures.py) and strict JSON.

Contract: :func:`write_report` writes ``report.txt`` and the figures into ``out_dir`` and
returns ``{"report": path, "fit": path, ...}``; :func:`write_json` writes
``result.to_json()`` as strict JSON (NaN/inf -> null, numpy scalars -> numbers).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tsa_bench.outputs import write_text
from tsa_bench.report.diagnose_figures import OUTPUT_UNITS, decimate_minmax, write_figures
from tsa_bench.report.diagnose_text import format_report

__all__ = ["format_report", "write_figures", "write_json", "write_report", "decimate_minmax", "OUTPUT_UNITS"]


def _jsonable(v: Any) -> Any:
    if isinstance(v, Mapping):
        return {str(k): _jsonable(w) for k, w in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(w) for w in v]
    if isinstance(v, np.ndarray):
        return [_jsonable(w) for w in v.tolist()]
    if isinstance(v, (np.bool_, bool)):
        return bool(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, (float, np.floating)):
        f = float(v)
        return f if math.isfinite(f) else None
    if isinstance(v, Path):
        return str(v)
    return v


def write_json(result: Any, path: str | Path) -> Path:
    """``result.to_json()`` as strict JSON (non-finite numbers -> null)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    data = result.to_json() if hasattr(result, "to_json") else dict(vars(result))
    write_text(p, json.dumps(_jsonable(data), indent=2, allow_nan=False) + "\n")
    return p


def write_report(result: Any, runs: Sequence[Any], out_dir: str | Path) -> dict[str, Path]:
    """Write report.txt and the figures into ``out_dir``; return ``{"report": ..., "fit": ..., ...}``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"report": out / "report.txt"}
    write_text(paths["report"], format_report(result, runs))
    paths.update(write_figures(result, out))
    return paths
