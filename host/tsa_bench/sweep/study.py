"""Study files: read, validate and expand a ``tsa-bench sweep`` study into points.

A study file (YAML, docs/sweep.md) holds::

    study: lifetime-creep            # name (text): names the results folder
    description: ...                 # optional text
    runner: simulate                 # simulate | diagnose | fit | reproduce
    seed: 7                          # seeds the random draws (integer, default 0)
    base:                            # parameters set for every point (nested sections)
      protocol: {shape: lifetime, load_g: 550}
    vary:                            # what varies: dotted parameter path -> values
      protocol.cycles: [10, 20, 40]                                # a list
      plant.effects.resistance_creep.ohm_per_turn: {grid: {start: 0, stop: 3e-5, num: 4}}
      bench.seed: {grid: {start: 0, stop: 3, step: 1}}
      plant.radius_mm: {random: {low: 0.45, high: 0.55, count: 3}}  # seeded draws
    keep: [drift_z, detected]        # optional: the figures of merit to keep (default all)
    report: {lines: [plant.effects.resistance_creep.ohm_per_turn]}   # optional: drawn as separate
                                     # lines in the figures (default: the varied text parameters)

Points are the Cartesian product of the varied values, in file order. Contract of
:func:`load_study`: every problem (an unknown parameter path, an empty list or grid, a
value of the wrong type, an unknown preset) raises :class:`DocumentError`
``"file:line:col: message"`` before any point runs. A point's key is a hash of its full
configuration (the resolved plant included) and the software version, so re-running a
study skips the points already in its results.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from yaml import MappingNode, ScalarNode

from tsa_bench import __version__
from tsa_bench.userfiles import DocumentError, YamlDocument, read_yaml
from tsa_bench.sweep import schema
from tsa_bench.sweep.effects import NAMES as EFFECT_NAMES

TOP_KEYS = ("study", "description", "runner", "seed", "base", "vary", "keep", "report")
MAX_POINTS = 1_000_000


@dataclass(frozen=True)
class Axis:
    """One varied parameter: its dotted path and its values, in order."""

    path: str
    values: tuple[Any, ...]


@dataclass(frozen=True)
class Point:
    """One point of a study: its index, key, full configuration and varied values."""

    index: int
    key: str
    config: dict[str, Any]
    varied: dict[str, Any]


@dataclass
class Study:
    """A validated study (module contract); ``runner`` may be a function for a study built in code."""

    name: str
    description: str
    runner: Any
    seed: int
    base: dict[str, Any]
    axes: list[Axis]
    keep: list[str] | None
    path: str = ""
    lines: list[str] | None = None
    points: list[Point] = field(default_factory=list)


def _fail(doc: YamlDocument, keys: tuple[str | int, ...], message: str, at_key: bool = False) -> DocumentError:
    node = _key_node(doc, keys) if at_key else None
    node = node if node is not None else doc.node(*keys)
    if node is not None:
        return doc.error(node, message)
    return DocumentError(doc.filename, None, None, message) if not keys else \
        DocumentError(*_split(doc.where(*keys)), message)


def _key_node(doc: YamlDocument, keys: tuple[str | int, ...]):
    """The key node of the last key of a mapping path (where an unknown name is written)."""
    parent = doc.node(*keys[:-1]) if keys else None
    if isinstance(parent, MappingNode):
        for k, _ in parent.value:
            if isinstance(k, ScalarNode) and k.value == keys[-1]:
                return k
    return None


def _split(where: str) -> tuple[str, int | None, int | None]:
    parts = where.rsplit(":", 2)
    if len(parts) == 3 and parts[1].isdigit() and parts[2].isdigit():
        return parts[0], int(parts[1]), int(parts[2])
    return where, None, None


def _flatten(data: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in data.items():
        path = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten(v, path + "."))   # an empty section sets nothing
        else:
            out[path] = v
    return out


def _number(doc: YamlDocument, keys: tuple[str | int, ...], v: Any, what: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _fail(doc, keys, f"{what} must be a number, got {v!r}")
    return v


def _axis_values(doc: YamlDocument, path: str, spec: Any, default: Any, seed: int) -> list[Any]:
    keys: tuple[str | int, ...] = ("vary", path)
    was_list = isinstance(spec, list)
    if was_list:
        spec = {"values": spec}
    if not isinstance(spec, dict) or len(spec) != 1 or next(iter(spec)) not in ("values", "grid", "random"):
        raise _fail(doc, keys, f"vary {path}: give a list of values or a mapping with one of values, grid, random")
    kind, body = next(iter(spec.items()))
    keys = keys if was_list else (*keys, kind)
    if kind == "values":
        if not isinstance(body, list):
            raise _fail(doc, keys, f"vary {path}: values must be a list")
        if not body:
            raise _fail(doc, keys, f"vary {path}: the list of values is empty (a study needs at least one)")
        return body
    if not isinstance(body, dict):
        raise _fail(doc, keys, f"vary {path}: {kind} must be a mapping")
    integer = isinstance(default, int) and not isinstance(default, bool)
    if kind == "grid":
        allowed = {"start", "stop", "num", "step", "log"}
        extra = sorted(set(body) - allowed)
        if extra or "start" not in body or "stop" not in body or ("num" in body) == ("step" in body):
            raise _fail(doc, keys, f"vary {path}: a grid takes start, stop and either num or step (and log)"
                        + (f"; unknown {', '.join(extra)}" if extra else ""))
        lo = _number(doc, (*keys, "start"), body["start"], "start")
        hi = _number(doc, (*keys, "stop"), body["stop"], "stop")
        log = bool(body.get("log", False))
        if log and (lo <= 0 or hi <= 0):
            raise _fail(doc, keys, f"vary {path}: a log grid needs start and stop > 0")
        if "num" in body:
            num = body["num"]
            if isinstance(num, bool) or not isinstance(num, int) or num < 1:
                raise _fail(doc, (*keys, "num"), f"vary {path}: the grid is empty (num must be an integer >= 1, "
                                                 f"got {num!r})")
            vals = np.geomspace(lo, hi, num) if log else np.linspace(lo, hi, num)
        else:
            step = _number(doc, (*keys, "step"), body["step"], "step")
            if step <= 0 or hi < lo or log:
                raise _fail(doc, keys, f"vary {path}: the grid is empty (step must be > 0 with start <= stop, "
                                       "and a log grid takes num)")
            vals = np.arange(0, int(np.floor((hi - lo) / step + 1e-9)) + 1) * step + lo
        out = [float(v) for v in vals]
        return [int(round(v)) for v in out] if integer else out
    allowed = {"low", "high", "count", "log", "choices"}
    extra = sorted(set(body) - allowed)
    count = body.get("count")
    if extra or isinstance(count, bool) or not isinstance(count, int):
        raise _fail(doc, keys, f"vary {path}: random takes count and either low/high (and log) or choices"
                    + (f"; unknown {', '.join(extra)}" if extra else ""))
    if count < 1:
        raise _fail(doc, (*keys, "count"), f"vary {path}: no draws (count must be >= 1, got {count})")
    rng = np.random.default_rng([seed, zlib.crc32(path.encode())])   # stable whatever the axis order
    if "choices" in body:
        choices = body["choices"]
        if not isinstance(choices, list) or not choices or "low" in body or "high" in body:
            raise _fail(doc, keys, f"vary {path}: choices must be a non-empty list (without low/high)")
        return [choices[int(i)] for i in rng.integers(0, len(choices), count)]
    if "low" not in body or "high" not in body:
        raise _fail(doc, keys, f"vary {path}: random takes low and high (or choices)")
    lo = _number(doc, (*keys, "low"), body["low"], "low")
    hi = _number(doc, (*keys, "high"), body["high"], "high")
    if hi < lo:
        raise _fail(doc, keys, f"vary {path}: high must be >= low")
    if body.get("log"):
        if lo <= 0:
            raise _fail(doc, keys, f"vary {path}: log draws need low > 0")
        draws = np.exp(rng.uniform(np.log(lo), np.log(hi), count))
    else:
        draws = rng.uniform(lo, hi, count)
    return [int(rng.integers(int(lo), int(hi) + 1)) for _ in draws] if integer else [float(v) for v in draws]


#: Longest study name (characters and UTF-8 bytes): it names the results folder (at most 255 bytes).
MAX_NAME_CHARS = 100


def load_study(path: str | Path) -> Study:
    """Read and validate a study file and expand its points (module contract)."""
    doc = read_yaml(path, what="study file")
    data = doc.data()
    if not isinstance(data, dict):
        raise DocumentError(doc.filename, None, None, "a study file is a mapping (study, runner, base, vary)")
    for k in data:
        if k not in TOP_KEYS:
            raise _fail(doc, (k,), f"unknown key {k!r} (allowed: {', '.join(TOP_KEYS)})")
    name = data.get("study")
    if not isinstance(name, str) or not name.strip() or any(c in name for c in "/\\\0") \
            or name.strip() in (".", ".."):
        raise _fail(doc, ("study",), "study: give the study a name (text without slashes, not '.' or '..': it "
                                     "names the results folder)")
    if len(name) > MAX_NAME_CHARS or len(name.encode("utf-8", "surrogatepass")) > MAX_NAME_CHARS:
        raise _fail(doc, ("study",), f"study: a name of {len(name):,} characters; at most {MAX_NAME_CHARS} "
                                     "(it names the results folder)")
    runner = data.get("runner")
    if runner not in schema.RUNNERS:
        raise _fail(doc, ("runner",), f"runner must be one of {', '.join(schema.RUNNERS)}, got {runner!r}")
    seed = data.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise _fail(doc, ("seed",), f"seed must be an integer >= 0, got {seed!r}")
    base = data.get("base") or {}
    vary = data.get("vary") or {}
    for key, v in (("base", base), ("vary", vary)):
        if not isinstance(v, dict):
            raise _fail(doc, (key,), f"{key} must be a mapping")
    shape = base.get("protocol", {}).get("shape") if isinstance(base.get("protocol"), dict) else None
    if runner != "reproduce" and shape is not None and shape not in schema.SHAPES:
        raise _fail(doc, ("base", "protocol", "shape"),
                    f"protocol.shape must be one of {', '.join(schema.SHAPES)}, got {shape!r}")
    tree = schema.defaults(runner, shape)
    choices = {**schema.CHOICES, "effect.name": EFFECT_NAMES, **_presets()}
    if runner == "reproduce":
        choices["reproduce.record"] = _record_ids()
    flat_base = _flatten(base)
    for p, v in flat_base.items():
        keys = ("base", *p.split("."))
        _check(doc, keys, tree, p, v, choices)
    axes = []
    for p, spec in vary.items():
        keys = ("vary", p)
        if p == "protocol.shape":
            raise _fail(doc, keys, "protocol.shape cannot vary (its parameters differ): write one study per shape")
        default = _known(doc, keys, tree, p)
        values = _axis_values(doc, p, spec, default, seed)
        for v in values:
            _check(doc, keys, tree, p, v, choices)
        axes.append(Axis(p, tuple(values)))
    keep = data.get("keep")
    if keep is not None and (not isinstance(keep, list) or not keep or not all(isinstance(k, str) for k in keep)):
        raise _fail(doc, ("keep",), "keep must be a non-empty list of figure names")
    report = data.get("report") or {}
    if not isinstance(report, dict) or set(report) - {"lines"}:
        raise _fail(doc, ("report",), "report takes lines: [varied parameters drawn as separate lines]")
    lines = report.get("lines")
    if lines is not None:
        if not isinstance(lines, list) or not all(isinstance(x, str) for x in lines):
            raise _fail(doc, ("report", "lines"), "report.lines must be a list of varied parameter paths")
        for i, x in enumerate(lines):
            if x not in vary:
                raise _fail(doc, ("report", "lines", i), f"report.lines: {x!r} is not a varied parameter "
                                                         f"(varied: {', '.join(vary) or 'none'})")
    n = int(np.prod([len(a.values) for a in axes])) if axes else 1
    if n > MAX_POINTS:
        raise _fail(doc, ("vary",), f"the study has {n:,} points (at most {MAX_POINTS:,})")
    study = Study(name.strip(), str(data.get("description") or ""), runner, seed, base, axes, keep, doc.filename,
                  lines=lines)
    study.points = expand(study, tree)
    return study


def _presets() -> dict[str, tuple[str, ...]]:
    from tsa_bench.shipped import shipped

    names = tuple(sorted(p.stem for p in shipped("bench").glob("*.yaml") if _has_plant(p)))
    return {"bench.preset": names, "diagnose.model": names}


def _record_ids() -> tuple[str, ...]:
    from tsa_bench.reproduce.records import load_records

    return tuple(r.id for r in load_records(None) if r.measure is not None)


def _has_plant(p: Path) -> bool:
    try:
        return "\nplant:" in "\n" + p.read_text(encoding="utf-8")
    except OSError:
        return False


def _known(doc: YamlDocument, keys: tuple[str | int, ...], tree: dict[str, Any], path: str) -> Any:
    try:
        return schema.leaf_default(tree, path)
    except KeyError as exc:
        raise _fail(doc, keys, str(exc.args[0]), at_key=True) from None


def _check(doc: YamlDocument, keys: tuple[str | int, ...], tree: dict[str, Any], path: str, value: Any,
           choices: dict[str, tuple[str, ...]]) -> None:
    default = _known(doc, keys, tree, path)
    if path in choices and value not in choices[path]:
        raise _fail(doc, keys, f"{path} must be one of {', '.join(choices[path])}, got {value!r}")
    why = schema.check_value(path, default, value)
    if why:
        raise _fail(doc, keys, why)


def expand(study: Study, tree: dict[str, Any] | None = None) -> list[Point]:
    """The study's points: the product of its axes over ``base`` on the runner's defaults."""
    from tsa_bench.sweep.plant import resolved_plant

    start = copy.deepcopy(tree if tree is not None else schema.defaults(study.runner))
    for p, v in _flatten(study.base).items():
        schema.set_path(start, p, v)
    points: list[Point] = []
    seen: set[str] = set()
    for combo in itertools.product(*(a.values for a in study.axes)):
        cfg = copy.deepcopy(start)
        varied = {}
        for axis, v in zip(study.axes, combo):
            schema.set_path(cfg, axis.path, v)
            varied[axis.path] = v
        if study.runner == "diagnose" and (cfg["effect"]["name"] == "none" or cfg["effect"]["magnitude"] == 0):
            cfg["effect"] = {"name": "none", "magnitude": 0.0}   # every clean point is the same point
            varied = {p: cfg["effect"][p.split(".")[1]] if p.startswith("effect.") else v
                      for p, v in varied.items()}
        key = point_key(study.runner, cfg, resolved_plant(study.runner, cfg))
        if key in seen:
            continue
        seen.add(key)
        points.append(Point(len(points), key, cfg, varied))
    return points


def point_key(runner: str, config: dict[str, Any], plant: dict[str, Any] | None) -> str:
    """Hash (16 hex digits) of a point's runner, configuration, resolved plant and the software version."""
    text = json.dumps({"runner": runner, "config": config, "plant": plant, "version": __version__},
                      sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]
