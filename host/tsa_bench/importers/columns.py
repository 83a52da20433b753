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
from tsa_bench.units import CHANNELS, DIMENSIONS, UnitError, channel_conversion, parse_unit, units_of

EXTRA_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,63}$")


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
    known = list(SAMPLE_COLUMNS) + [c for c in CHANNELS if c not in SAMPLE_COLUMNS]
    if target in known:
        return
    close = difflib.get_close_matches(target, known, n=1, cutoff=0.8)
    if close or not EXTRA_NAME.match(target):
        hint = f"did you mean '{close[0]}'? " if close else ""
        raise ImportFileError(f"--map: unknown target '{target}' ({hint}targets: {', '.join(SAMPLE_COLUMNS)}; "
                              f"channels: {', '.join(known[len(SAMPLE_COLUMNS):])}; or an extra column "
                              "named with letters, digits and _, unlike these)")


def _extra_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]+", "_", name.strip()).strip("_")[:64]


def resolve(table: SourceTable, mapping: dict[str, str] | None, timed: bool,
            reserved: tuple[int, ...] = ()) -> tuple[list[Choice], dict[int, str]]:
    """([chosen columns], {left-out column index: why}); see the module contract."""
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
    if timed and "t" not in targets and table.time_s is None:
        if mapping:
            raise ImportFileError("--map: 't' (time) must be mapped, e.g. --map t=time_s,... "
                                  "(or give --sample-period when the file has no time column)")
        raise ImportFileError(f"{table.where()}: no column named 't' in the header {table.names}; "
                              "give --map t=YOUR_TIME_COLUMN,... (or --sample-period when the file has no time)")
    if not timed and "t" in {c.target for c in chosen if c.how == "mapped"}:
        raise ImportFileError("--sample-period synthesises t from the row order; do not also map t")
    return chosen, left


def _conversion(target: str, unit: str, where: str) -> tuple[float, float, str]:
    if target in CHANNELS:
        unit = "1" if unit.strip() in ("-", "[-]") else unit
        try:
            f, o = channel_conversion(target, unit)
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


def units_for(table: SourceTable, chosen: list[Choice], units: dict[str, str]) -> None:
    """Fill each choice's unit, stored unit and conversion (module contract); raise on conflicts."""
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
        suffix = name_unit(c.target, name) if c.target in CHANNELS else suffix_unit(name)[1]
        where = f"{table.where()}: column {table.label(c.index)} ({c.target})"
        if given:
            _conversion(c.target, given, where)  # an unknown unit is named before any conflict
            declared = head or suffix
            if declared and not same_unit(declared, given):
                problems.append(f"{where}: the header says '{declared}' but --units says '{given}'; "
                                "they disagree: fix the header or drop the --units entry")
                continue
        unit = given or head or suffix
        if not unit and _needs_unit(c.target):
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
