"""What the user declares at import: constant columns, scale, offset and sign, and a word on impossible values.

Contract:

* :func:`quantity` reads ``VALUE[UNIT]`` (``200g``, ``1.96 N``, ``-12.5``) into (value, unit text).
* :func:`constants` turns ``--const NAME=VALUE[UNIT]`` (and ``--load-g G``, ``load=Gg``) into
  {target: (value in the target's stored unit, stored unit, what was given)}; a target that a
  source column already fills is refused (one source per column).
* :func:`keyed` names the columns ``--scale``, ``--offset`` and ``--negate`` act on (a run-file
  column, or a source column by its name) and refuses others; :func:`apply` applies them to
  the converted values, in
  that order: ``stored = offset + scale x (-1 if negated) x value``; scale and offset are in
  the stored unit (an offset may carry a unit of its own dimension, ``--offset length=25cm``).
  A scale with a unit (``--scale length=2.5mm/V``) is a calibration: it is applied by
  :func:`tsa_bench.importers.columns.units_for`, the source unit times the scale's unit giving
  the target's.
* :func:`impossible` names the values no rig can measure - a negative length, resistance or
  declared load, a resistance below the wires' (``WIRES_OHM``) - with the count, the extreme
  and the option that fixes each.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from tsa_bench.importers.errors import ImportFileError
from tsa_bench.rundocs import SAMPLE_COLUMNS
from tsa_bench.units import CHANNELS, UnitError, channel_conversion, parse_unit

#: a resistance below this (ohm) is less than the leads to the string: not a string's resistance
WIRES_OHM = 0.1
_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")


def quantity(text: str, option: str) -> tuple[float, str]:
    """(value, unit) of ``VALUE[UNIT]``; ImportFileError naming ``option`` when it is not one."""
    m = _QUANTITY.match(text)
    if not m:
        raise ImportFileError(f"{option}: '{text}' is not a number with an optional unit (e.g. 200g, 1.5, 2.5mm/V)")
    return float(m.group(1)), m.group(2)


def _to_stored(target: str, value: float, unit: str, option: str) -> tuple[float, str]:
    """``value`` in ``unit`` as the stored unit of ``target`` (a channel, or an extra column keeping ``unit``)."""
    if target in CHANNELS:
        try:
            f, o = channel_conversion(target, unit)
        except UnitError as exc:
            raise ImportFileError(f"{option}: {target}: {exc}") from None
        return value * f + o, CHANNELS[target].unit
    if target in SAMPLE_COLUMNS:
        raise ImportFileError(f"{option}: {target} is a column the run file fills itself; it cannot be declared")
    return value, unit


def constants(pairs: dict[str, str], taken: set[str]) -> dict[str, tuple[float, str, str]]:
    """{target: (value in its stored unit, stored unit, as given)} (module contract)."""
    out = {}
    for target, text in pairs.items():
        if target in taken:
            raise ImportFileError(f"--const {target}={text}: {target} already comes from a source column; "
                                  "drop the column (--map) or the --const")
        value, unit = quantity(text, f"--const {target}")
        if target == "t":
            raise ImportFileError("--const t: time cannot be constant (give --sample-period for a file without time)")
        if target not in CHANNELS and not unit:
            raise ImportFileError(f"--const {target}={text}: an extra column needs a unit (e.g. {text}degC), "
                                  "or 1 for a pure number")
        stored, stored_unit = _to_stored(target, value, unit, f"--const {target}")
        out[target] = (stored, stored_unit, text)
    return out


def scales(pairs: dict[str, str]) -> tuple[dict[str, float], dict[str, str]]:
    """({column: factor}, {column: unit of a calibration}) of ``--scale COLUMN=F[UNIT]``."""
    factors, calibrations = {}, {}
    for key, text in pairs.items():
        factors[key], unit = quantity(text, f"--scale {key}")
        if unit:
            calibrations[key] = unit
    return factors, calibrations


def keyed(scale: dict[str, str], offset: dict[str, str], negate: list[str], targets: list[str],
          names: dict[str, str]) -> tuple[dict[str, float], dict[str, str], dict[str, tuple[float, str]], set[str]]:
    """(factors, calibrations, offsets, negated) keyed by run-file column: a key is one of ``targets`` or a
    source column's name (``names`` {name: target}); anything else is refused naming the columns."""
    def key(k: str, option: str) -> str:
        if k in targets:
            return k
        if k in names:
            return names[k]
        raise ImportFileError(f"{option} {k}: no such column among the imported ones ({', '.join(targets)})")

    factors, calibrations = scales(scale)
    return ({key(k, "--scale"): f for k, f in factors.items()},
            {key(k, "--scale"): u for k, u in calibrations.items()},
            {key(k, "--offset"): quantity(v, f"--offset {k}") for k, v in offset.items()},
            {key(k, "--negate") for k in negate})


def apply(data: dict[str, np.ndarray], units: dict[str, str], scale: dict[str, float],
          offset: dict[str, tuple[float, str]], negate: set[str], calibrations: dict[str, str]) -> list[str]:
    """Negate, scale and offset ``data`` in place (module contract); one summary line per column changed.
    The factor of a calibration (``calibrations`` {column: unit}) is already in the conversion: said, not applied."""
    lines = []
    for k in sorted(set(scale) | set(offset) | negate, key=list(data).index):
        v = data[k]
        parts = []
        if k in negate:
            v = -v
            parts.append("negated")
        if k in calibrations:
            parts.append(f"calibrated x{scale[k]:g} {calibrations[k]}")
        elif k in scale:
            v = v * scale[k]
            parts.append(f"x{scale[k]:g}")
        if k in offset:
            x, unit = offset[k]
            x, _ = _to_stored(k, x, unit, f"--offset {k}") if unit else (x, "")
            v = v + x
            parts.append(f"{x:+g} {units.get(k, '')}".rstrip())
        data[k] = v
        lines.append(f"  {k}: {', then '.join(parts)} (--negate/--scale/--offset)")
    return lines


def _span(v: np.ndarray, mask: np.ndarray, unit: str) -> str:
    return f"{int(mask.sum())} row{'s' if mask.sum() != 1 else ''}, {np.min(v[mask]):.6g} to {np.max(v[mask]):.6g} {unit}"


def impossible(data: dict[str, Any]) -> list[str]:
    """Warnings naming impossible values and the option that fixes each (module contract)."""
    out = []
    length = data.get("length")
    if length is not None and (neg := np.isfinite(length) & (length < 0)).any():
        out.append(f"length is negative ({_span(length, neg, 'mm')}): a length cannot be. A stage position or "
                   "displacement is not a length: --negate length and/or --offset length=L0 (the length at "
                   "position 0), or map it as an extra column (--map position=COLUMN)")
    r = data.get("resistance")
    if r is not None:
        fin = np.isfinite(r)
        if (neg := fin & (r < 0)).any():
            out.append(f"resistance is negative ({_span(r, neg, 'ohm')}): a resistance cannot be. A meter "
                       "reporting the sign of an AC or reversed measurement: --negate resistance")
        if (low := fin & (r >= 0) & (r < WIRES_OHM)).any():
            out.append(f"resistance below {WIRES_OHM:g} ohm ({_span(r, low, 'ohm')}): less than the wires leading "
                       "to the string. A unit read wrong (kohm or Mohm values read as ohm)? Give the unit: "
                       "--units resistance=kohm, or --scale resistance=FACTOR")
    load = data.get("load")
    if load is not None and (neg := np.isfinite(load) & (load < 0)).any():
        out.append(f"the declared load is negative ({_span(load, neg, 'N')}): a hanging load pulls. --negate load, "
                   "or map a measured force as force (--map force=COLUMN)")
    return out
