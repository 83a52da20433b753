"""Write a calibration into a new bench file, keeping everything else as written.

Contract: :func:`calibrated_text` edits the bench YAML text in place of the values it
changes (``position_sensor.mm_per_count``/``offset_mm`` or
``resistance_sensor.gain``/``offset_ohm``, inserted when absent), appends the
calibration record to ``calibrations:`` (created at the end of the file when absent)
and puts a comment line naming the calibration at the top; comments, order and every
other value stay as they were. The result is read back with the bench reader and must
give the fitted values, else :class:`BenchWriteError`. :func:`write_new_bench` writes
it to a new file (never over an existing one) through a temporary name.
"""

from __future__ import annotations

import os
from pathlib import Path

import yaml
from yaml import MappingNode, ScalarNode, SequenceNode

from tsa_bench.bench import BenchConfigError, parse_bench
from tsa_bench.outputs import OutputExists, write_text
from tsa_bench.userfiles import DocumentError, parse_yaml

SECTIONS = {"position": "position_sensor", "resistance": "resistance_sensor"}


class BenchWriteError(ValueError):
    """The calibrated bench file cannot be written; the message says why."""


def _number(x: float) -> str:
    return repr(float(f"{x:.10g}"))


def _child(mapping: MappingNode, key: str) -> tuple[ScalarNode, object] | None:
    for k, v in mapping.value:
        if isinstance(k, ScalarNode) and k.value == key:
            return k, v
    return None


def _line_end(text: str, index: int) -> int:
    end = text.find("\n", index)
    return len(text) if end < 0 else end


def calibrated_text(text: str, filename: str, quantity: str, result: dict[str, float], record: dict) -> str:
    """The bench text with ``result`` written and ``record`` appended (module contract)."""
    try:
        doc = parse_yaml(text, filename)
    except DocumentError as exc:
        raise BenchWriteError(str(exc)) from None
    root = doc.root
    if not isinstance(root, MappingNode):
        raise BenchWriteError(f"{filename}: not a bench file (a mapping of keys)")
    section = SECTIONS[quantity]
    found = _child(root, section)
    if found is None or not isinstance(found[1], MappingNode):
        raise BenchWriteError(f"{filename}: no {section} mapping to write the calibration into")
    mapping = found[1]
    edits: list[tuple[int, int, str]] = []   # (start, end, replacement), applied from the end
    missing = []
    for key, value in result.items():
        hit = _child(mapping, key)
        if hit is None:
            missing.append((key, value))
        elif not isinstance(hit[1], ScalarNode):
            raise BenchWriteError(f"{doc.where(section, key)}: {section}.{key} is not a number to replace")
        else:
            node = hit[1]
            edits.append((node.start_mark.index, node.end_mark.index, _number(value)))
    if missing:
        if mapping.flow_style:
            close = mapping.end_mark.index - 1          # the closing brace
            edits.append((close, close, "".join(f", {k}: {_number(v)}" for k, v in missing)))
        else:
            indent = mapping.value[0][0].start_mark.column if mapping.value else 2
            last = mapping.value[-1][1] if mapping.value else found[0]
            at = _line_end(text, max(last.end_mark.index - 1, 0))
            edits.append((at, at, "".join(f"\n{' ' * indent}{k}: {_number(v)}" for k, v in missing)))
    item = yaml.safe_dump([record], sort_keys=False, default_flow_style=None, width=1000, allow_unicode=True)
    records = _child(root, "calibrations")
    if records is None:
        tail = "" if text.endswith("\n") else "\n"
        tail += "# Calibration records (tsa-bench calibrate), newest last.\ncalibrations:\n"
        tail += "".join(f"  {line}\n" for line in item.splitlines())
        edits.append((len(text), len(text), tail))
    else:
        seq = records[1]
        if isinstance(seq, ScalarNode) and seq.tag.endswith(":null"):
            at = _line_end(text, records[0].start_mark.index)
            edits.append((at, at, "\n" + "".join(f"  {line}\n" for line in item.splitlines()).rstrip("\n")))
        elif not isinstance(seq, SequenceNode) or seq.flow_style:
            raise BenchWriteError(f"{doc.where('calibrations')}: calibrations must be a block list (one '- ' item "
                                  "per record) to append a record")
        else:
            indent = seq.value[0].start_mark.column if seq.value else 2
            at = _line_end(text, max(seq.end_mark.index - 1, 0))
            prefix = " " * max(indent - 2, 0)
            edits.append((at, at, "\n" + "\n".join(f"{prefix}{line}" for line in item.splitlines())))
    out = text
    for start, end, new in sorted(edits, key=lambda e: (e[0], e[1]), reverse=True):
        out = out[:start] + new + out[end:]
    header = f"# {quantity} calibrated by tsa-bench calibrate on {record['date']} (from {Path(filename).name})\n"
    return header + out


def write_new_bench(text: str, source: str, out: str | Path, quantity: str, result: dict[str, float],
                    record: dict) -> Path:
    """Write the calibrated bench to ``out`` (module contract); returns its path."""
    path = Path(out)
    if os.path.lexists(path):
        raise BenchWriteError(f"{path} already exists; choose another --out (bench files are never overwritten)")
    new = calibrated_text(text, source, quantity, result, record)
    try:
        bench = parse_bench(new, str(path), allow_url=True, trust_firmware_dir=True)
    except BenchConfigError as exc:
        raise BenchWriteError(f"the calibrated bench file would not be valid: {exc}") from None
    got = ({"mm_per_count": bench.position.mm_per_count, "offset_mm": bench.position.offset_mm}
           if quantity == "position" else {"gain": bench.resistance.gain, "offset_ohm": bench.resistance.offset_ohm})
    for key, value in result.items():
        if abs(got[key] - value) > 1e-9 * max(1.0, abs(value)):
            raise BenchWriteError(f"writing {key} failed: the new file reads {got[key]!r}, not {value!r}")
    try:
        write_text(path, new, force=False)
    except OutputExists:
        raise BenchWriteError(f"{path} already exists; choose another --out (bench files are never overwritten)") \
            from None
    except OSError as exc:
        raise BenchWriteError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path
