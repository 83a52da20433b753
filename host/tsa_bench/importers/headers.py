"""Column names and the units written in them.

A header cell gives its unit as ``name [unit]``, ``name (unit)``, ``name/unit`` (``t/s``,
only when what follows the first ``/`` is a known unit) or, for a column taken as a
named channel, ``name_unit`` (``time_ms``, ``R_kohm``). Names are matched to targets
case-insensitively and through a few common synonyms (``time`` -> ``t``, ``load cell``
-> ``force``: a measured force is never the declared ``load``).
"""

from __future__ import annotations

import re

from tsa_bench.rundocs import SAMPLE_COLUMNS
from tsa_bench.units import CHANNELS, AmbiguousUnitError, UnitError, channel_conversion, parse_unit

_BRACKETS = re.compile(r"^\s*(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]\s*$")

#: other spellings of a target, lower case, as lab files write them
SYNONYMS: dict[str, str] = {
    "time": "t", "zeit": "t", "temp": "temperature", "load cell": "force", "loadcell": "force",
    "load_cell": "force", "force sensor": "force", "measured force": "force", "twist": "turns",
    "heater voltage": "heater_voltage", "len": "length", "resistance": "resistance",
}

#: one-letter symbols, taken only when the column's unit is of the channel's dimension (``R_ohm``, ``F (N)``)
SYMBOLS: dict[str, str] = {"R": "resistance", "r": "resistance", "L": "length", "F": "force", "f": "force",
                           "T": "temperature", "p": "pressure", "P": "pressure", "I": "current", "U": "voltage",
                           "V": "voltage"}


def split_header(cell: str) -> tuple[str, str]:
    """(name, unit) of a header cell; unit "" when the cell gives none in brackets or after '/'."""
    m = _BRACKETS.match(cell)
    if m:
        return m.group(1), m.group(2)
    name = cell.strip()
    if "/" in name:
        head, _, tail = name.partition("/")
        if head.strip() and tail.strip():
            try:
                parse_unit(tail.strip())
            except AmbiguousUnitError:
                pass  # a unit, if an ambiguous one: refused when converted
            except UnitError:
                return name, ""
            return head.strip(), tail.strip()
    return name, ""


def target_of(name: str) -> str | None:
    """The contract column or channel a column name stands for (case-insensitive, synonyms), or None."""
    if len(name.strip()) == 1:  # one letter: case matters (t is time, T a temperature: see SYMBOLS)
        return name.strip() if name.strip() in CHANNELS else None
    low = name.strip().lower()
    for cand in (low, low.replace(" ", "_")):
        if cand in CHANNELS or cand in SAMPLE_COLUMNS:
            return cand
        if cand in SYNONYMS:
            return SYNONYMS[cand]
    if "_" in low:  # name_unit: time_ms, r_kohm -> only when the suffix is a unit of that channel
        base, suffix = low.rsplit("_", 1)
        tgt = target_of(base) if base else None
        if tgt and name_unit(tgt, name):
            return tgt
    return None


def suffix_unit(name: str) -> tuple[str, str]:
    """(name, unit) of ``name_unit`` when the part after the last ``_`` is a known unit, else (name, "")."""
    if "_" in name:
        base, suffix = name.rsplit("_", 1)
        if base and suffix:
            try:
                parse_unit(suffix)
            except AmbiguousUnitError:
                return base, suffix  # a unit, if an ambiguous one: refused (naming both readings) when converted
            except UnitError:
                return name, ""
            return base, suffix
    return name, ""


def guess_target(name: str, unit: str) -> str | None:
    """The target of an unmapped column: its name (:func:`target_of`) or a one-letter symbol whose
    channel the unit fits."""
    tgt = target_of(name)
    if tgt is None and name.strip() in SYMBOLS and unit:
        cand = SYMBOLS[name.strip()]
        try:
            channel_conversion(cand, unit)
        except AmbiguousUnitError:
            return cand  # refused when converted, naming both readings
        except UnitError:
            return None
        return cand
    return tgt


def name_unit(target: str, name: str) -> str:
    """The unit at the end of a column name (``time_ms`` -> ``ms``), if it is one for ``target``."""
    if "_" not in name or target not in CHANNELS:
        return ""
    suffix = name.rsplit("_", 1)[1]
    try:
        channel_conversion(target, suffix)
    except AmbiguousUnitError:
        return suffix
    except UnitError:
        return ""
    return suffix


def same_unit(a: str, b: str) -> bool:
    """Whether two unit spellings mean the same unit (``Ohm`` and ``ohm``, ``degC`` and ``C``)."""
    if a == b:
        return True
    try:
        ua, ub = parse_unit(a), parse_unit(b)
    except UnitError:
        return a.lower() == b.lower()
    return ua.signature == ub.signature and abs(ua.factor - ub.factor) <= 1e-12 * abs(ub.factor) \
        and ua.offset == ub.offset
