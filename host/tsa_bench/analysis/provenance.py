"""Where a diagnosis came from: input files and model with sha256, software, settings.

Contract: :func:`provenance` returns a JSON-ready mapping; :func:`sha256_file` hashes a
file in 1 MiB chunks (None if it cannot be read).
"""

from __future__ import annotations

import hashlib
import platform
from datetime import datetime, timezone
from pathlib import Path
from typing import Any


def sha256_file(path: str | Path) -> str | None:
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
    except OSError:
        return None
    return h.hexdigest()


def _version(name: str) -> str | None:
    try:
        from importlib.metadata import version
        return version(name)
    except Exception:
        return None


def provenance(runs: list, model_path: str | Path | None, model_text: str, holdout: dict, seed: int,
               seconds: float) -> dict[str, Any]:
    return {
        "inputs": [{"path": str(getattr(r, "path", "")), "sha256": sha256_file(getattr(r, "path", "")),
                    "samples": len(r), "exit_status": getattr(r, "exit_status", None)} for r in runs],
        "model": {"path": str(model_path) if model_path else None,
                  "sha256": sha256_file(model_path) if model_path else None,
                  "plant_sha256": hashlib.sha256(model_text.encode()).hexdigest()},
        "holdout": holdout.get("spec"),
        "software": {"tsa_bench": _version("tsa-bench"), "python": platform.python_version(),
                     "numpy": _version("numpy"), "scipy": _version("scipy")},
        "seed": seed,
        "seconds": round(seconds, 3),
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
