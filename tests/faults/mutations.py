"""Bad inputs for every kind of file a user hands tsa-bench, made by mutating good ones.

A mutation is a list of operations ``(op, position, pick)`` applied in order, so the
same list always makes the same file: hypothesis draws and shrinks the lists
(tests/faults/test_mutation.py), scripts/fuzz_inputs.py draws thousands at random.

* text files (protocols, bench files, manipulator files, CSVs, model JSON): a value
  replaced by a nasty one (a 5000-digit integer, 1e308, .inf, NaN, a lone surrogate,
  ``$`` mathtext, control characters, YAML tags, anchors), lines deleted, duplicated,
  swapped or re-indented, characters flipped, the file truncated, an alias bomb or
  deep nesting added;
* run files (HDF5): columns removed, retyped, reshaped, unequal, filled with NaN, inf,
  1e308 or time running backwards; attributes removed or retyped; soft and external
  links (one to a FIFO); /segments and /events with wrong fields or huge indices;
  bytes flipped or the file truncated.
"""

from __future__ import annotations

import os
import random
import re
from collections.abc import Sequence
from pathlib import Path

import h5py
import numpy as np

Op = tuple[str, int, int]

NASTY_VALUES: tuple[str, ...] = (
    "9" * 5000, "1e308", "-1e308", "1.0e999", ".nan", ".inf", "-.inf", "''", "null", "[]", "{}", "true",
    '"\\ud800"', '"$\\\\frac{1}{0}$ $x"', "0x7fffffffffffffff", "-0", "1e-320", "2001-01-01",
    "!!binary aGVsbG8=", "!!python/object/apply:os.system ['true']", "*undefined", "&a [*a]", "~",
    "-1", "0", "4294967.296", "4294967296", "1e15", "65.536", "-2147483649", '"\\x00"', "\x01", "?",
    "{a: 1, a: 2}", "[" * 200, "!custom 3", "<<: {x: 1}", "'a\nb'",
)
TEXT_OPS = ("value", "value", "value", "delete_line", "duplicate_line", "swap_lines", "indent", "flip_char",
            "truncate", "alias_bomb", "deep_nesting", "key_value")
ALIAS_BOMB = ("bomb0: &b0 [x, x, x, x, x, x, x, x, x]\n" +
              "".join(f"bomb{i}: &b{i} [{', '.join([f'*b{i - 1}'] * 9)}]\n" for i in range(1, 8)))
FLIP_CHARS = "\x00\x01\x1b\t\r{}[]:,&*!|>'\"%@`#-?\\$\ud800\uffff\u00e9\u202e"
_VALUE = re.compile(r"(?m)(:\s+|-\s+|,\s*|\[\s*)([^\s,\[\]{}#][^,\[\]{}#\n]*)")


def apply_text(text: str, ops: Sequence[Op]) -> str:
    """Apply text mutations (module docstring); never raises."""
    for op, pos, pick in ops:
        lines = text.split("\n")
        if op == "value":
            spots = list(_VALUE.finditer(text))
            if spots:
                m = spots[pos % len(spots)]
                text = text[:m.start(2)] + NASTY_VALUES[pick % len(NASTY_VALUES)] + text[m.end(2):]
        elif op == "key_value":
            i = pos % max(1, len(lines))
            lines.insert(i, f"{('x', 'name', 'steps', 'limits', 'plant', 'port', 'backend')[pick % 7]}: "
                            f"{NASTY_VALUES[pick % len(NASTY_VALUES)]}")
            text = "\n".join(lines)
        elif op == "delete_line" and lines:
            del lines[pos % len(lines)]
            text = "\n".join(lines)
        elif op == "duplicate_line" and lines:
            i = pos % len(lines)
            lines.insert(i, lines[i])
            text = "\n".join(lines)
        elif op == "swap_lines" and len(lines) > 1:
            i, j = pos % len(lines), pick % len(lines)
            lines[i], lines[j] = lines[j], lines[i]
            text = "\n".join(lines)
        elif op == "indent" and lines:
            i = pos % len(lines)
            lines[i] = " " * (pick % 7) + lines[i].lstrip() if pick % 2 else lines[i].lstrip()
            text = "\n".join(lines)
        elif op == "flip_char" and text:
            i = pos % len(text)
            text = text[:i] + FLIP_CHARS[pick % len(FLIP_CHARS)] + text[i + 1:]
        elif op == "truncate" and text:
            text = text[:pos % len(text)]
        elif op == "alias_bomb":
            text = ALIAS_BOMB + text
        elif op == "deep_nesting":
            depth = 50 + pick % 5000
            text += f"\ndeep: {'[' * depth}{']' * depth}\n"
    return text


def write_text(path: Path, text: str) -> Path:
    """Write possibly un-encodable text (lone surrogates) as the bytes a careless editor would."""
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    return path


CSV_NASTY = ("40000", "-40000", "1e400", "nan", "", "inf", "-inf", "1e308", "0x10", "1,5", '"', "9" * 400,
             "4294967296", "-1", "2.5", "\x00", "\ud800", "1e15", "-1e16")
CSV_OPS = ("cell", "cell", "cell", "delete_line", "duplicate_line", "swap_lines", "flip_char", "truncate",
           "header", "extra_column", "reverse_time")


def apply_csv(text: str, ops: Sequence[Op]) -> str:
    """CSV mutations: cells replaced by nasty values, rows and header broken, time reversed."""
    for op, pos, pick in ops:
        lines = text.split("\n")
        if op == "cell" and len(lines) > 1:
            i = 1 + pos % (len(lines) - 1)
            cells = lines[i].split(",")
            cells[pick % len(cells)] = CSV_NASTY[(pos // 7 + pick) % len(CSV_NASTY)]
            lines[i] = ",".join(cells)
        elif op == "header" and lines:
            cells = lines[0].split(",")
            cells[pick % len(cells)] = ("t", "t [ms]", "length [furlong]", "", "x [", "position_raw",
                                        "counter [1]")[pos % 7]
            lines[0] = ",".join(cells)
        elif op == "extra_column" and len(lines) > 1:
            i = pos % len(lines)
            lines[i] += ",1"
        elif op == "reverse_time" and len(lines) > 2:
            lines = [lines[0], *reversed(lines[1:])]
        else:
            return apply_csv(apply_text(text, [(op, pos, pick)]), [])
        text = "\n".join(lines)
    return text


JSON_NASTY: tuple[object, ...] = (None, True, "text", "\ud800", 10**45, 1e308, float("nan"), float("inf"), [], {},
                                  [[1, 2], [3]], list(range(10)), -1, 0, 10**6, {"value": 1}, "$x$")
JSON_OPS = ("replace", "replace", "delete", "text")


def apply_json(doc: object, text: str, ops: Sequence[Op]) -> str:
    """Model-file mutations: values in the JSON tree replaced or deleted, or the text broken."""
    import copy
    import json

    tree = copy.deepcopy(doc)
    broken: list[Op] = []
    for op, pos, pick in ops:
        if op == "text":
            broken.append((TEXT_OPS[pick % len(TEXT_OPS)], pos, pick))
            continue
        paths: list[tuple[object, object]] = []
        stack = [tree]
        while stack:
            node = stack.pop()
            items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
            for k, v in items:
                paths.append((node, k))
                stack.append(v)
        if not paths:
            continue
        parent, key = paths[pos % len(paths)]
        if op == "delete" and isinstance(parent, dict):
            del parent[key]
        else:
            parent[key] = JSON_NASTY[pick % len(JSON_NASTY)]
    out = json.dumps(tree, allow_nan=True, ensure_ascii=False)
    return apply_text(out, broken) if broken else out


RUN_OPS = ("drop_column", "retype_column", "reshape_column", "shorten_column", "nan", "inf", "huge", "backwards",
           "drop_attr", "retype_attr", "soft_link", "external_link", "fifo_link", "segments", "events",
           "segment_index", "flip_bytes", "truncate", "units", "config", "string_column", "empty")
COLUMNS = ("t", "turns", "length", "resistance", "heater_voltage", "load", "segment", "motor_moving", "counter")


def mutate_run(src: Path, dst: Path, ops: Sequence[Op]) -> Path:
    """A damaged copy of run file ``src`` at ``dst`` (module docstring)."""
    dst.write_bytes(src.read_bytes())
    byte_ops = []
    with h5py.File(dst, "a") as f:
        g = f["samples"]
        for op, pos, pick in ops:
            try:
                _run_op(f, g, op, pos, pick, dst, byte_ops)
            except (OSError, KeyError, ValueError, TypeError, RuntimeError, IndexError):
                pass  # an earlier operation made this one impossible: skip it
    raw = bytearray(dst.read_bytes())
    for op, pos, pick in byte_ops:
        if op == "flip_bytes" and raw:
            for k in range(1 + pick % 16):
                raw[(pos + 7919 * k) % len(raw)] ^= 1 + (pick + k) % 255
        elif op == "truncate" and raw:
            del raw[pos % len(raw):]
    dst.write_bytes(bytes(raw))
    return dst


def _run_op(f: h5py.File, g: h5py.Group, op: str, pos: int, pick: int, dst: Path, byte_ops: list) -> None:
    """One HDF5-level operation of :func:`mutate_run` (byte-level ones are queued)."""
    name = COLUMNS[pos % len(COLUMNS)]
    if name not in g and op not in ("drop_attr", "retype_attr", "segments", "events", "segment_index",
                                    "flip_bytes", "truncate", "config", "empty", "external_link",
                                    "fifo_link"):
        return
    hard = name in g and isinstance(g.get(name, getlink=True), h5py.HardLink)
    if op in ("retype_column", "reshape_column", "string_column", "shorten_column", "nan", "inf", "huge",
              "backwards", "units") and not hard:
        return  # a link made by an earlier operation: do not follow it here
    if op == "drop_column":
        del g[name]
    elif op in ("retype_column", "reshape_column", "string_column", "shorten_column"):
        data, units = g[name][()], g[name].attrs.get("units", "")
        del g[name]
        if op == "retype_column":
            new = data.astype(np.complex128)
        elif op == "reshape_column":
            new = np.stack([data, data], axis=1)
        elif op == "string_column":
            new = np.array([b"x"] * len(data))
        else:
            new = data[: max(0, len(data) - 1 - pick % 50)]
        g.create_dataset(name, data=new).attrs["units"] = units
    elif op in ("nan", "inf", "huge", "backwards"):
        data = g[name][()]
        if data.dtype.kind not in "biuf" or data.ndim != 1:
            return
        data = data.astype(float)
        if len(data):
            i = pick % len(data)
            data[i] = {"nan": np.nan, "inf": np.inf, "huge": 1e308, "backwards": -1e3}[op]
            units = g[name].attrs.get("units", "")
            del g[name]
            g.create_dataset(name, data=data).attrs["units"] = units
    elif op == "units":
        g[name].attrs["units"] = ("m", "", "s", "ohm", b"\xff\xfe", 3)[pick % 6]
    elif op == "drop_attr":
        key = ("format", "exit_status", "plan_name", "reason")[pick % 4]
        if key in f.attrs:
            del f.attrs[key]
    elif op == "retype_attr":
        key = ("format", "exit_status", "plan_name", "created", "metadata")[pick % 5]
        f.attrs[key] = (np.arange(3), 42, b"\xff\xfe\xfd", "$x$ \ud800".encode("utf-8", "surrogatepass"),
                        np.array([b"tsa-bench/run"]), "running")[pos % 6]
    elif op == "soft_link":
        del g[name]
        g[name] = h5py.SoftLink("/samples/t")
    elif op in ("external_link", "fifo_link"):
        target = dst.with_name(dst.name + ".target")
        if op == "fifo_link":
            if not target.exists():
                os.mkfifo(target)
        if name in g:
            del g[name]
        g[name] = h5py.ExternalLink(str(target), "/samples/t")
    elif op == "segments":
        if "segments" in f:
            del f["segments"]
        f.create_dataset("segments", data=(np.zeros(3), np.zeros((2, 2)),
                                           np.zeros(2, dtype=[("index", "f8")]),
                                           np.zeros(2, dtype=[("index", "i4"), ("kind", "i4"),
                                                              ("t_start", "f8"), ("t_end", "S3")]))[pick % 4])
    elif op == "segment_index" and "segments" in f and len(f["segments"]):
        seg = f["segments"][()]
        seg["index"][pick % len(seg)] = (2**31 - 1, -5, 10**8)[pos % 3]
        del f["segments"]
        f.create_dataset("segments", data=seg)
    elif op == "events":
        if "events" in f:
            del f["events"]
        f.create_dataset("events", data=(np.zeros(3), np.zeros(2, dtype=[("t", "S2"), ("kind", "S2")]),
                                         np.zeros(2, dtype=[("t", "f8"), ("kind", "S2")]))[pick % 3])
    elif op == "config":
        if "config/protocol" in f:
            del f["config/protocol"]
        f.create_dataset("config/protocol", data=(np.arange(5), "x" * (pick % 1000))[pos % 2])
    elif op == "empty":
        for column in list(g):
            data, units = g[column][()], g[column].attrs.get("units", "")
            del g[column]
            g.create_dataset(column, data=data[:0]).attrs["units"] = units
    else:
        byte_ops.append((op, pos, pick))


def random_ops(rng: random.Random, kinds: Sequence[str], most: int = 3) -> list[Op]:
    return [(rng.choice(kinds), rng.randrange(10**6), rng.randrange(10**6)) for _ in range(rng.randint(1, most))]
