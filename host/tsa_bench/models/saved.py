"""The saved-model JSON format: parameters with units, training files and metrics.

Units: every parameter is stored as ``{"value": number or list, "unit": text}``.

Contract: :func:`save_model` writes::

    {"format": "tsa-bench/model", "format_version": "1.0", "model": <name>,
     "input": {"column", "unit"}, "output": {"column", "unit"},
     "parameters": {<name>: {"value", "unit"}, ...}, "options": {...},
     "training_files": [...], "metrics": {"identification": {file: {...}}, "validation": {file: {...}}},
     "created": ISO time}

:func:`load_model_file` reads it back with the hardened JSON reader
(:mod:`tsa_bench.userfiles`: a regular file of at most 64 MB, nesting, integer and
text limits) and raises :class:`ModelFileError` whose message starts with the file
name and says what is wrong (missing file, not JSON, wrong format, unknown model,
missing parameter, a parameter that is not a finite number or a list of them, a
Preisach model whose size does not match its weights).
"""

from __future__ import annotations

import datetime as dt
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tsa_bench.outputs import write_text

FORMAT = "tsa-bench/model"
FORMAT_VERSION = "1.0"
MODEL_NAMES = ("preisach", "polynomial", "strain-resistance", "self-sensing", "twist-heat-additive",
               "twist-heat-coupled")
#: Largest Preisach discretisation read back (the thesis uses M = 20).
MAX_PREISACH_LEVELS = 200
#: Longest list parameter read back.
MAX_LIST = 100_000


class ModelFileError(ValueError):
    """A model file that cannot be used; the message names the file and the problem."""


@dataclass
class SavedModel:
    """What a model file holds (module docstring); ``parameters[name] = {"value", "unit"}``."""

    model: str
    input: dict[str, str]
    output: dict[str, str]
    parameters: dict[str, dict[str, Any]]
    options: dict[str, Any] = field(default_factory=dict)
    training_files: list[str] = field(default_factory=list)
    metrics: dict[str, dict[str, Any]] = field(default_factory=lambda: {"identification": {}, "validation": {}})
    created: str = ""

    def value(self, name: str) -> Any:
        try:
            return self.parameters[name]["value"]
        except KeyError:
            raise ModelFileError(f"model '{self.model}': parameter '{name}' is missing") from None

    def as_json(self) -> dict[str, Any]:
        return {"format": FORMAT, "format_version": FORMAT_VERSION, "model": self.model, "input": self.input,
                "output": self.output, "parameters": self.parameters, "options": self.options,
                "training_files": self.training_files, "metrics": self.metrics,
                "created": self.created or dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")}


def param(value: Any, unit: str) -> dict[str, Any]:
    """One stored parameter."""
    return {"value": value, "unit": unit}


def save_model(saved: SavedModel, path: str | Path) -> Path:
    return write_text(path, json.dumps(saved.as_json(), indent=1, allow_nan=True) + "\n")


def load_model_file(path: str | Path) -> SavedModel:
    """Read and check a model file; raise ModelFileError naming the file and the problem."""
    from tsa_bench.userfiles import DocumentError, read_json

    p = Path(path)
    if not p.exists():
        raise ModelFileError(f"{p}: no such file")
    try:
        doc = read_json(p, what="model file")
    except DocumentError as exc:
        raise ModelFileError(f"{exc.where}: not a usable JSON model file ({exc.message})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise ModelFileError(f"{p}: 'format' is {got!r}, expected {FORMAT!r}")
    if doc.get("model") not in MODEL_NAMES:
        raise ModelFileError(f"{p}: unknown model {doc.get('model')!r} (known: {', '.join(MODEL_NAMES)})")
    for key in ("input", "output", "parameters"):
        if not isinstance(doc.get(key), dict):
            raise ModelFileError(f"{p}: '{key}' is missing or not a mapping")
    for key in ("input", "output"):
        if not all(isinstance(doc[key].get(k), str) for k in ("column", "unit")):
            raise ModelFileError(f"{p}: '{key}' must be {{\"column\": text, \"unit\": text}}")
    for name, entry in doc["parameters"].items():
        if not isinstance(entry, dict) or "value" not in entry or "unit" not in entry:
            raise ModelFileError(f"{p}: parameter '{name}' must be {{\"value\": ..., \"unit\": ...}}")
        if not _numbers(entry["value"]):
            raise ModelFileError(f"{p}: parameter '{name}' must be a finite number or a list of at most "
                                 f"{MAX_LIST:,} of them")
    for key, kind in (("options", dict), ("metrics", dict), ("training_files", list), ("created", str)):
        if key in doc and not isinstance(doc[key], kind):
            raise ModelFileError(f"{p}: '{key}' must be a {kind.__name__}")
    saved = SavedModel(doc["model"], doc["input"], doc["output"], doc["parameters"], doc.get("options", {}),
                       list(doc.get("training_files", [])),
                       doc.get("metrics", {"identification": {}, "validation": {}}), doc.get("created", ""))
    if saved.model == "preisach":
        _check_preisach(p, saved)
    return saved


def _numbers(value: Any) -> bool:
    """A finite number (not a boolean), or a flat list of at most MAX_LIST of them."""
    if isinstance(value, list):
        return len(value) <= MAX_LIST and all(_numbers(v) and not isinstance(v, list) for v in value)
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _check_preisach(p: Path, saved: SavedModel) -> None:
    levels, weights = saved.value("levels"), saved.value("weights")
    if not (isinstance(levels, int) or float(levels).is_integer()) or not 1 <= levels <= MAX_PREISACH_LEVELS:
        raise ModelFileError(f"{p}: preisach 'levels' must be a whole number 1..{MAX_PREISACH_LEVELS}, got {levels}")
    m = int(levels)
    if not isinstance(weights, list) or len(weights) != m * (m + 1) // 2:
        raise ModelFileError(f"{p}: preisach 'weights' must list M(M+1)/2 = {m * (m + 1) // 2} values for "
                             f"M = {m} levels")
    if not float(saved.value("u_max")) > float(saved.value("u_min")):
        raise ModelFileError(f"{p}: preisach 'u_max' must be above 'u_min'")
