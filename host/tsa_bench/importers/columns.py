"""Which source column becomes which run-file column, in which unit.

Contract of :func:`resolve` and :func:`units_for`:

* ``mapping`` {target: source column}: a source column is named by its full header text,
  by its name without the unit, case-insensitively, or by its 1-based position (``3``),
  the only way for a file without a header. A target is a contract sample column of
  docs/run-format.md, a channel of :data:`tsa_bench.units.CHANNELS` or any other name of
  letters, digits and ``_`` (an extra column).
* Columns not mapped are still picked up (a partial ``--map`` keeps the rest): a column
  whose name is a contract column or channel (case-insensitive, synonyms of
  :mod:`.headers`: ``time`` -> t, ``load cell`` -> force) and any column whose header gives
  a unit (an extra column, its name made of letters, digits and ``_``). Every other
  column is left out, with the reason in the summary.
* A unit comes from ``units`` (by target, header text or name), else the header, else the
  format (TDMS), else a unit at the end of the name (``time_ms``). A header unit and a
  ``units`` entry that disagree are an error naming both. Contract columns and channels
  are converted to their stored unit; a physical column without a unit is refused.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass

from tsa_bench.importers.errors import ImportFileError
from tsa_bench.importers.headers import guess_target, name_unit, same_unit, split_header, suffix_unit
from tsa_bench.importers.table import SourceTable
from tsa_bench.rundocs import SAMPLE_COLUMNS
from tsa_bench.units import (CHANNELS, DIMENSIONS, AmbiguousUnitError, UnitError, channel_conversion, multiply,
                             parse_unit, units_of)

EXTRA_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,63}$")
#: names labs give a time column (lower case, unit removed), taken as t when nothing else is
TIME_NAMES = re.compile(r"^(elapsed([ _]?time)?|time[ _]?elapsed|time[ _]?stamps?|timestamps?|x[ _]?values?|"
                        r"seconds|secs?|run[ _]?time|(abs|absolute|rel|relative)[ _]?time|time[ _]?s(ec)?)$")
#: channels a transducer's output is often named for (an LVDT's "Voltage" stands for a displacement)
TRANSDUCER_OUTPUTS = ("voltage", "current")


@dataclass
class Choice:
    """Where source column ``index`` goes: ``target``, from ``unit`` (as given) to ``stored``."""

    target: str
    index: int
    how: str  # "mapped" or "picked up"
    unit: str = ""
    stored: str = ""
    factor: float = 1.0
    offset: float = 0.0

    @property
    def kind(self) -> str:
        return "contract column" if self.target in SAMPLE_COLUMNS else "extra column"


def _find(table: SourceTable, ref: str) -> int | None:
    """Index of the source column ``ref`` names (header text, bare name, either case, or position)."""
    names = table.names
    if table.has_header:
        bare = [split_header(n)[0] for n in names]
        for pool, key in ((names, ref), (bare, ref), ([b.lower() for b in bare], ref.lower()),
                          ([n.lower() for n in names], ref.lower())):
            if key in pool:
                return pool.index(key)
    if ref.isdigit() and 1 <= int(ref) <= len(names):
        return int(ref) - 1
    return None


def _check_target(target: str) -> None:
    """Refuse a target that is neither known nor an extra name, or a misspelling of a known one (``lenght``);
    a name built from a known one (``t_force``, ``force_2``) is an extra column."""
    known = list(SAMPLE_COLUMNS) + [c for c in CHANNELS if c not in SAMPLE_COLUMNS]
    if target in known:
        return
    close = difflib.get_close_matches(target, known, n=1, cutoff=0.8)
    if any(part in known for part in target.split("_")):
        close = []
    if close or not EXTRA_NAME.match(target):
        hint = f"did you mean '{close[0]}'? " if close else ""
        raise ImportFileError(f"--map: unknown target '{target}' ({hint}targets: {', '.join(SAMPLE_COLUMNS)}; "
                              f"channels: {', '.join(known[len(SAMPLE_COLUMNS):])}; or an extra column "
                              "named with letters, digits and _, unlike these)")


def _extra_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]+", "_", name.strip()).strip("_")[:64]


def _is_time_name(raw: str) -> bool:
    name, unit = split_header(raw)
    if not unit:
        name = suffix_unit(name)[0]
    return bool(TIME_NAMES.match(name.strip().lower()))


def _guess_time(table: SourceTable, chosen: list[Choice], left: dict[int, str], mapped: set[int],
                reserved: tuple[int, ...]) -> list[str]:
    """Take t from the one column named as labs name time (:data:`TIME_NAMES`); notes saying so."""
    cands = [i for i, col in enumerate(table.columns)
             if i not in mapped and i not in reserved and col.name and table.has_header and _is_time_name(col.name)]
    if len(cands) > 1:
        raise ImportFileError(f"{table.where()}: no column named 't'; several could be time "
                              f"({', '.join(table.label(i) for i in cands)}): choose one with --map t=COLUMN")
    if not cands:
        return []
    i = cands[0]
    chosen[:] = [c for c in chosen if c.index != i]
    left.pop(i, None)
    chosen.append(Choice("t", i, "guessed"))
    return [f"t guessed from column {table.label(i)} (a common name for time; --map t=COLUMN chooses another)"]


def resolve(table: SourceTable, mapping: dict[str, str] | None, timed: bool,
            reserved: tuple[int, ...] = ()) -> tuple[list[Choice], dict[int, str], list[str]]:
    """([chosen columns], {left-out column index: why}, [notes]); see the module contract."""
    chosen: list[Choice] = []
    taken: dict[int, str] = {}
    for target, ref in (mapping or {}).items():
        _check_target(target)
        i = _find(table, ref)
        if i is None:
            if table.has_header:
                raise ImportFileError(f"{table.where()}: column '{ref}' (mapped to {target}) is not in the header; "
                                      f"columns are: {', '.join(table.names)}")
            raise ImportFileError(f"{table.path}: no column {ref!r} (mapped to {target}): the file has no header; "
                                  f"name columns by position 1..{len(table.columns)}, e.g. --map t=1")
        if i in reserved:
            raise ImportFileError(f"--map {target}={ref}: column {table.label(i)} is the segment column "
                                  "(--segments column=...); it cannot also be mapped")
        chosen.append(Choice(target, i, "mapped"))
        taken[i] = target
    left: dict[int, str] = {}
    notes: list[str] = []
    targets = {c.target for c in chosen}
    for i, col in enumerate(table.columns):
        if i in taken:
            continue
        if i in reserved:
            left[i] = "read as the segment column (--segments column=...)"
            continue
        if not table.has_header or not col.name:
            left[i] = f"no name: map it by position (--map NAME={i + 1})"
            continue
        name, unit = split_header(col.name)
        unit = unit or col.unit
        tgt = guess_target(name, unit)
        if tgt is None and not unit:
            base, unit = suffix_unit(name)
            tgt = guess_target(base, unit) if unit else None
            if tgt is None and unit:
                name = base
        if tgt is None and unit and EXTRA_NAME.match(_extra_name(name) or "-"):
            tgt = _extra_name(name)
            if tgt in CHANNELS or tgt.lower() in CHANNELS:
                tgt = tgt.lower()
        if tgt is None:
            left[i] = "not a contract column or channel name and no unit in its header (--map NAME=..., --units)"
        elif tgt in targets:
            other = next(c for c in chosen if c.target == tgt)
            left[i] = f"{tgt} is already taken from column {table.label(other.index)}"
        elif tgt == "t" and not timed:
            left[i] = "t comes from --sample-period"
        else:
            chosen.append(Choice(tgt, i, "picked up"))
            targets.add(tgt)
            if tgt in TRANSDUCER_OUTPUTS:
                notes.append(f"column {table.label(i)} is taken as the measured {tgt} by its name alone; if it is "
                             "a transducer's output standing for another quantity, map that quantity with its "
                             f"calibration (mm per {unit or 'V'}), e.g. --map length={name} --scale length=2.5mm/{unit or 'V'}")
    if timed and "t" not in targets and table.time_s is None:
        notes += _guess_time(table, chosen, left, set(taken), reserved)
        targets = {c.target for c in chosen}
    if timed and "t" not in targets and table.time_s is None:
        if mapping:
            raise ImportFileError("--map: 't' (time) must be mapped, e.g. --map t=time_s,... "
                                  "(or give --sample-period when the file has no time column)")
        raise ImportFileError(f"{table.where()}: no column named 't' in the header {table.names}; "
                              "give --map t=YOUR_TIME_COLUMN,... (or --sample-period when the file has no time)")
    if not timed and "t" in {c.target for c in chosen if c.how == "mapped"}:
        raise ImportFileError("--sample-period synthesises t from the row order; do not also map t")
    return chosen, left, notes


def _ambiguous(exc: AmbiguousUnitError, target: str, where: str) -> ImportFileError:
    return ImportFileError(f"{where}: {exc} (say which with --units {target}=UNIT, e.g. "
                           f"--units {target}={exc.readings[0]})")


def _conversion(target: str, unit: str, where: str) -> tuple[float, float, str]:
    if target in CHANNELS:
        unit = "1" if unit.strip() in ("-", "[-]") else unit
        try:
            f, o = channel_conversion(target, unit)
        except AmbiguousUnitError as exc:
            raise _ambiguous(exc, target, where) from None
        except UnitError as exc:
            reduced = _reduced(target, unit)  # mm/mm for a strain, N*m/m for a force ...
            if reduced is not None:
                return reduced, 0.0, CHANNELS[target].unit
            allowed = str(exc).split("use one of: ", 1)[-1]
            raise ImportFileError(f"{where}: unit '{unit}' is not known for {target} "
                                  f"({CHANNELS[target].dimension}); use one of: {allowed}") from None
        return f, o, CHANNELS[target].unit
    if target in SAMPLE_COLUMNS:
        contract = SAMPLE_COLUMNS[target][1]
        if unit not in ("", contract):
            raise ImportFileError(f"{where}: unit '{unit}' is not known for {target}; use one of: {contract}")
        return 1.0, 0.0, contract
    try:  # an extra column keeps its unit as written; only an ambiguous one is refused
        parse_unit(unit)
    except AmbiguousUnitError as exc:
        raise _ambiguous(exc, target, where) from None
    except UnitError:
        pass
    return 1.0, 0.0, unit


def _reduced(target: str, unit: str) -> float | None:
    """The factor of a compound unit that reduces to ``target``'s dimension (``mm/mm`` for a strain), or None."""
    ch = CHANNELS[target]
    try:
        u = parse_unit(unit)
    except UnitError:
        return None
    want = () if ch.dimension == "dimensionless" else ((ch.dimension, 1),)
    if u.signature != want or u.offset:
        return None
    return u.factor / DIMENSIONS[ch.dimension][ch.unit][0]


def _needs_unit(target: str) -> bool:
    if target in CHANNELS:
        return CHANNELS[target].dimension != "dimensionless"
    return target not in SAMPLE_COLUMNS


def _calibrated(target: str, unit: str, factor: float, by: str, where: str) -> tuple[float, str]:
    """(factor to the stored unit, unit text) of a column in ``unit`` calibrated by ``factor`` ``by``
    (``V`` x 2.5 ``mm/V`` -> mm): the product must have the target's dimension."""
    if target not in CHANNELS:
        raise ImportFileError(f"--scale {target}={factor:g}{by}: a scale with a unit is for contract columns and "
                              f"channels; for an extra column give the factor alone and its unit with --units")
    ch = CHANNELS[target]
    try:
        u = multiply(parse_unit(unit), parse_unit(by))
    except AmbiguousUnitError as exc:
        raise _ambiguous(exc, target, where) from None
    except UnitError as exc:
        raise ImportFileError(f"{where}: --scale {target}: {exc}") from None
    want = () if ch.dimension == "dimensionless" else ((ch.dimension, 1),)
    if u.signature != want:
        raise ImportFileError(f"{where}: --scale {target}={factor:g}{by}: {unit} x {by} is {u.dimension_text}, "
                              f"not {ch.dimension} ({target} is stored in {ch.unit})")
    return factor * u.factor / DIMENSIONS[ch.dimension][ch.unit][0], f"{unit} x {factor:g} {by}"


def units_for(table: SourceTable, chosen: list[Choice], units: dict[str, str],
              calibrations: dict[str, tuple[float, str]] | None = None) -> None:
    """Fill each choice's unit, stored unit and conversion (module contract); raise on conflicts.
    ``calibrations`` {target: (factor, unit)} (``--scale length=2.5mm/V``) convert a column whose unit is
    not the target's: its unit times the calibration's gives the target's."""
    calibrations = calibrations or {}
    names = table.names
    bare = [split_header(n)[0] for n in names]
    for key in units:
        if key not in {c.target for c in chosen} and key not in names and key not in bare:
            raise ImportFileError(f"--units: '{key}' is neither a mapped column nor a source column")
    problems: list[str] = []
    for c in chosen:
        raw = names[c.index]
        name, head = split_header(raw)
        head = head or table.columns[c.index].unit
        given = units.get(c.target) or (raw and units.get(raw)) or (name and units.get(name)) or ""
        calibrated = c.target in calibrations
        suffix = name_unit(c.target, name) if c.target in CHANNELS and not calibrated else suffix_unit(name)[1]
        where = f"{table.where()}: column {table.label(c.index)} ({c.target})"
        if given:
            if not calibrated:
                _conversion(c.target, given, where)  # an unknown unit is named before any conflict
            declared = head or suffix
            if declared and not same_unit(declared, given):
                problems.append(f"{where}: the header says '{declared}' but --units says '{given}'; "
                                "they disagree: fix the header or drop the --units entry")
                continue
        unit = given or head or suffix
        if calibrated and unit:
            c.factor, c.unit = _calibrated(c.target, unit, *calibrations[c.target], where)
            c.stored = CHANNELS[c.target].unit
            continue
        if not unit and (_needs_unit(c.target) or calibrated):
            if c.target in CHANNELS:
                accepted = units_of(CHANNELS[c.target].dimension) + (["g", "kg"] if c.target == "load" else [])
                problems.append(f"{where} has no unit: give it in the header ('{name or c.target} "
                                f"[{CHANNELS[c.target].unit}]') or with --units {c.target}=UNIT ({', '.join(accepted)})")
            else:
                problems.append(f"{where}: extra column {c.target} has no unit; give one in the header "
                                f"('{name} [unit]') or with --units {c.target}=UNIT (use 1 for a pure number)")
            continue
        c.factor, c.offset, c.stored = _conversion(c.target, unit, where)
        c.unit = unit or c.stored
    if problems:
        raise ImportFileError("\n".join(problems))
