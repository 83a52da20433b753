"""The saved-model JSON format: parameters with units, training files and metrics.

Units: every parameter is stored as ``{"value": number or list, "unit": text}``.

Contract: :func:`save_model` writes::

    {"format": "tsa-bench/model", "format_version": "1.0", "model": <name>,
     "input": {"column", "unit"}, "output": {"column", "unit"},
     "parameters": {<name>: {"value", "unit"}, ...}, "options": {...},
     "training_files": [...], "metrics": {"identification": {file: {...}}, "validation": {file: {...}}},
     "created": ISO time}

:func:`load_model_file` reads it back and raises :class:`ModelFileError` whose message
starts with the file name and says what is wrong (missing file, not JSON, wrong
format, unknown model, missing parameter).
"""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

FORMAT = "tsa-bench/model"
FORMAT_VERSION = "1.0"
MODEL_NAMES = ("preisach", "polynomial", "strain-resistance", "self-sensing")


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
    path = Path(path)
    path.write_text(json.dumps(saved.as_json(), indent=1, allow_nan=True) + "\n", encoding="utf-8")
    return path


def load_model_file(path: str | Path) -> SavedModel:
    """Read and check a model file; raise ModelFileError naming the file and the problem."""
    p = Path(path)
    if not p.exists():
        raise ModelFileError(f"{p}: no such file")
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFileError(f"{p}: not a JSON model file ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise ModelFileError(f"{p}: 'format' is {got!r}, expected {FORMAT!r}")
    if doc.get("model") not in MODEL_NAMES:
        raise ModelFileError(f"{p}: unknown model {doc.get('model')!r} (known: {', '.join(MODEL_NAMES)})")
    for key in ("input", "output", "parameters"):
        if not isinstance(doc.get(key), dict):
            raise ModelFileError(f"{p}: '{key}' is missing or not a mapping")
    for name, entry in doc["parameters"].items():
        if not isinstance(entry, dict) or "value" not in entry or "unit" not in entry:
            raise ModelFileError(f"{p}: parameter '{name}' must be {{\"value\": ..., \"unit\": ...}}")
    return SavedModel(doc["model"], doc["input"], doc["output"], doc["parameters"], doc.get("options", {}),
                      list(doc.get("training_files", [])),
                      doc.get("metrics", {"identification": {}, "validation": {}}), doc.get("created", ""))
