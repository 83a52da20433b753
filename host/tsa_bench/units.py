"""Physical units: one table of the units tsa-bench accepts, their dimensions and conversions.

Units: every dimension has a base unit (the first in its table, factor 1); a value ``v``
in unit ``u`` is ``v * factor + offset`` in the base unit (offsets exist only for
temperatures).

Contract:

* :data:`DIMENSIONS` maps a dimension to ``{unit: (factor, offset)}``, every SI prefix
  (:data:`PREFIXES`: G, M, k, h, c, m, u/µ, n) a unit takes included. SI prefixes are
  case-sensitive: ``Mohm`` is a megaohm, ``mohm`` a milliohm, ``mPa`` a millipascal. A
  spelling that is no unit in its own case is read in another only when that gives one
  unit (``OHM``, ``Kohm``, ``MS``); when it gives two (``MOHM``, ``MPA``) it is refused
  with :class:`AmbiguousUnitError` naming both readings.
* :func:`parse_unit` reads a simple unit (``mm``, ``degC``) or a product/quotient of
  simple units with integer powers (``cm/turn^2``, ``ohm/cm``, ``1/s``, ``deg/s``,
  ``N*m``) and returns a :class:`Unit`: its dimension signature (``{dimension:
  power}``), the factor to the base units and the offset. A unit nobody knows raises
  :class:`UnitError` naming it. Offsets are refused inside compound units.
* :func:`convert` converts a value between two units of the same signature and raises
  :class:`UnitError` otherwise; :func:`units_of` lists the simple units of a dimension
  (for "allowed units" messages).
* :data:`CHANNELS` is the shared table of named sample channels: the contract columns
  of docs/run-format.md and the extra channels other rigs bring (temperature, force,
  pressure, stress, strain, current), each with its dimension and the unit it is stored
  in. The importers (:mod:`tsa_bench.importers`) and the thesis records
  (:mod:`tsa_bench.reproduce.records`) both read it.
"""

from __future__ import annotations

import math
import re
import unicodedata
from dataclasses import dataclass

#: SI prefixes, exact case: ``M`` is mega and ``m`` milli, never folded into each other
PREFIXES: dict[str, float] = {"G": 1e9, "M": 1e6, "k": 1e3, "h": 1e2, "c": 1e-2, "m": 1e-3, "u": 1e-6,
                              "\u00b5": 1e-6, "\u03bc": 1e-6, "n": 1e-9}
PREFIX_NAMES = {"G": "giga", "M": "mega", "k": "kilo", "h": "hecto", "c": "centi", "m": "milli", "u": "micro",
                "\u00b5": "micro", "\u03bc": "micro", "n": "nano"}
_MICRO = "u\u00b5\u03bc"
#: The weight of one gram under standard gravity, N (a hanging mass in g -> the load in N).
G_N_PER_G = 9.80665e-3

#: dimension -> [(spellings of one unit, factor to the dimension's base unit, offset, prefixes it takes)];
#: the first spelling of the first entry is the base. Prefixed spellings are made from these.
_BASES: dict[str, list[tuple[tuple[str, ...], float, float, str]]] = {
    "dimensionless": [(("1",), 1.0, 0.0, ""), (("%",), 0.01, 0.0, ""), (("ppm",), 1e-6, 0.0, ""),
                      (("strain",), 1.0, 0.0, _MICRO)],
    "time": [(("s",), 1.0, 0.0, "m" + _MICRO), (("min",), 60.0, 0.0, ""), (("h",), 3600.0, 0.0, "")],
    # twist and angles are one dimension: a motor turn is 360 degrees
    "angle": [(("turn", "turns", "rev", "rotation"), 1.0, 0.0, ""), (("deg", "\u00b0"), 1.0 / 360.0, 0.0, ""),
              (("rad",), 1.0 / (2.0 * math.pi), 0.0, "m")],
    "length": [(("m",), 1000.0, 0.0, "cm" + _MICRO + "n"), (("in",), 25.4, 0.0, "")],
    "resistance": [(("ohm", "Ohm", "\u03a9", "\u2126"), 1.0, 0.0, "GMkm" + _MICRO)],
    "voltage": [(("V",), 1.0, 0.0, "Mkm" + _MICRO)],
    "current": [(("A",), 1.0, 0.0, "km" + _MICRO + "n")],
    "force": [(("N",), 1.0, 0.0, "Mkm" + _MICRO), (("lbf",), 4.4482216152605, 0.0, "")],
    "mass": [(("g",), 1.0, 0.0, "Mkm" + _MICRO)],
    "temperature": [(("degC", "C", "\u00b0C"), 1.0, 0.0, ""), (("K",), 1.0, -273.15, ""),
                    (("degF", "\u00b0F"), 5.0 / 9.0, -32.0 * 5.0 / 9.0, "")],
    "pressure": [(("Pa",), 1e-3, 0.0, "GMkhm"), (("bar",), 100.0, 0.0, "m"), (("psi",), 6.894757293168, 0.0, ""),
                 (("ksi",), 6894.757293168, 0.0, "")],
    "power": [(("W",), 1.0, 0.0, "Mkm" + _MICRO)],
    "energy": [(("J",), 1.0, 0.0, "Mkm" + _MICRO)],
}
#: the base unit of each dimension (factor 1): what DIMENSIONS lists first
_BASE_UNIT = {"dimensionless": "1", "time": "s", "angle": "turn", "length": "mm", "resistance": "ohm",
              "voltage": "V", "current": "A", "force": "N", "mass": "g", "temperature": "degC",
              "pressure": "kPa", "power": "W", "energy": "J"}


def _table() -> dict[str, dict[str, tuple[float, float]]]:
    out: dict[str, dict[str, tuple[float, float]]] = {}
    for dim, bases in _BASES.items():
        units: dict[str, tuple[float, float]] = {}
        for spellings, f, o, prefixes in bases:
            for sp in spellings:
                units[sp] = (f, o)
                for p in prefixes:
                    units[p + sp] = (f * PREFIXES[p], o)
        base = _BASE_UNIT[dim]
        out[dim] = {base: units.pop(base), **units}
    return out


#: dimension -> {unit: (factor to the base unit, offset)}; the first unit is the base. Every SI
#: prefix a unit takes is listed, in its exact case (``mohm`` milliohm, ``Mohm`` megaohm).
DIMENSIONS: dict[str, dict[str, tuple[float, float]]] = _table()

#: unit spelling -> dimension (exact spellings; see :func:`_lookup` for other cases)
_BY_UNIT: dict[str, str] = {u: d for d, table in DIMENSIONS.items() for u in table}


@dataclass(frozen=True)
class Channel:
    """A named sample channel: its dimension and the unit it is stored in."""

    dimension: str
    unit: str
    doc: str


#: name -> channel. The first block are the contract columns of docs/run-format.md (the
#: ``load`` column also accepts masses, converted with g0); the second the extra channels
#: other rigs record. A CSV column mapped to a name here must come in a unit of its dimension.
CHANNELS: dict[str, Channel] = {
    "t": Channel("time", "s", "device time since the run started"),
    "turns": Channel("angle", "turn", "motor position"),
    "length": Channel("length", "mm", "TSA length"),
    "resistance": Channel("resistance", "ohm", "string resistance"),
    "heater_voltage": Channel("voltage", "V", "equivalent DC heater voltage"),
    "load": Channel("force", "N", "hanging load (a mass in g or kg is converted with g0)"),
    # extra channels
    "temperature": Channel("temperature", "degC", "temperature of the actuator or its surroundings"),
    "force": Channel("force", "N", "measured force"),
    "pressure": Channel("pressure", "kPa", "pressure"),
    "stress": Channel("pressure", "MPa", "mechanical stress"),
    "strain": Channel("dimensionless", "1", "strain (length change / reference length)"),
    "current": Channel("current", "A", "electric current"),
    "voltage": Channel("voltage", "V", "measured voltage"),
    "angle": Channel("angle", "deg", "an angle (e.g. a bending angle)"),
}

G0_M_PER_S2 = 9.80665


class UnitError(ValueError):
    """A unit that is unknown or does not fit the quantity; the message names both."""


class AmbiguousUnitError(UnitError):
    """A spelling that is no unit in its own case and two units in another (``MOHM``); names both."""

    def __init__(self, text: str, readings: list[str]) -> None:
        self.text, self.readings = text, readings
        super().__init__(f"unit '{text}' is ambiguous: it could be {' or '.join(_reading(u) for u in readings)}; "
                         "SI prefixes are case-sensitive (M mega, m milli): write the one meant")


@dataclass(frozen=True)
class Unit:
    """A parsed unit: ``signature`` {dimension: power}, ``factor`` and ``offset`` to the base units."""

    text: str
    signature: tuple[tuple[str, int], ...]
    factor: float
    offset: float = 0.0

    def to_base(self, value: float) -> float:
        return value * self.factor + self.offset

    def from_base(self, value: float) -> float:
        return (value - self.offset) / self.factor

    @property
    def dimension_text(self) -> str:
        """Readable signature, e.g. ``length/angle^2``."""
        return signature_text(self.signature)


def signature_text(signature: tuple[tuple[str, int], ...]) -> str:
    if not signature:
        return "dimensionless"
    num = [d if p == 1 else f"{d}^{p}" for d, p in signature if p > 0]
    den = [d if p == -1 else f"{d}^{-p}" for d, p in signature if p < 0]
    return ("*".join(num) or "1") + ("/" + "/".join(den) if den else "")


def _lookup(name: str) -> tuple[str, float, float] | None:
    """(dimension, factor, offset) of a simple unit, or None.

    The exact spelling wins (SI prefixes are case-sensitive). Another case (``OHM``, ``Kohm``,
    ``MS``) is read only when every known unit it could be has one value; when it could be
    two (``MOHM``: megaohm or milliohm) :class:`AmbiguousUnitError` names both readings.
    """
    dim = _BY_UNIT.get(name)
    if dim is None:
        folded = [u for u in _BY_UNIT if u.lower() == name.lower()]
        readings: dict[tuple[str, float, float], str] = {}
        for u in folded:
            f, o = DIMENSIONS[_BY_UNIT[u]][u]
            readings.setdefault((_BY_UNIT[u], f, o), u)
        if len(readings) > 1:
            raise AmbiguousUnitError(name, list(readings.values()))
        if not readings:
            return None
        name, dim = folded[0], _BY_UNIT[folded[0]]
    f, o = DIMENSIONS[dim][name]
    return dim, f, o


def _reading(unit: str) -> str:
    """``Mohm`` -> ``Mohm (mega, = 1e+06 ohm)``: one reading of a spelling, for messages."""
    dim = _BY_UNIT[unit]
    f, _ = DIMENSIONS[dim][unit]
    base = next(iter(DIMENSIONS[dim]))
    prefix = next((PREFIX_NAMES[p] for p in PREFIXES if len(unit) > len(p) and unit.startswith(p)
                   and unit not in {sp for b in _BASES[dim] for sp in b[0]}), "")
    return f"{unit} ({prefix + ', ' if prefix else ''}= {f:g} {base})"


_TERM = re.compile(r"^([^\^]+?)(?:\^(-?\d+))?$")


def parse_unit(text: str) -> Unit:
    """Parse a unit (module contract); raise UnitError naming an unknown part."""
    s = str(text).strip()
    if not s:
        raise UnitError("empty unit")
    hit = _lookup(s)
    if hit is not None:
        dim, f, o = hit
        sig = () if dim == "dimensionless" else ((dim, 1),)
        return Unit(s, sig, f, o)
    powers: dict[str, int] = {}
    factor = 1.0
    parts = s.split("/")
    for k, part in enumerate(parts):
        sign = 1 if k == 0 else -1
        for term in part.split("*"):
            m = _TERM.match(term.strip())
            if not m:
                raise UnitError(f"cannot read unit '{s}' (part '{term}')")
            name, power = m.group(1).strip(), int(m.group(2) or 1)
            hit = _lookup(name)
            if hit is None:
                raise UnitError(f"unknown unit '{name}' in '{s}'")
            dim, f, o = hit
            if o:
                raise UnitError(f"'{name}' has an offset (a temperature scale) and cannot be part of '{s}'")
            factor *= f ** (sign * power)
            if dim != "dimensionless":
                powers[dim] = powers.get(dim, 0) + sign * power
    sig = tuple(sorted((d, p) for d, p in powers.items() if p))
    return Unit(s, sig, factor, 0.0)


def multiply(a: Unit, b: Unit) -> Unit:
    """The product of two units (``V`` x ``mm/V`` = ``mm``); offsets are refused, as in compound units."""
    if a.offset or b.offset:
        raise UnitError(f"'{a.text if a.offset else b.text}' has an offset (a temperature scale) and cannot be "
                        "multiplied by another unit")
    powers = dict(a.signature)
    for d, p in b.signature:
        powers[d] = powers.get(d, 0) + p
    return Unit(f"{a.text}*{b.text}", tuple(sorted((d, p) for d, p in powers.items() if p)), a.factor * b.factor)


def units_of(dimension: str) -> list[str]:
    """The simple units of ``dimension`` for messages: base unit first, then each unit in all its
    spellings and with the ASCII prefixes it takes, in their exact case (``kohm``, ``Mohm``)."""
    out = [_BASE_UNIT[dimension]]
    for spellings, _, _, prefixes in _BASES[dimension]:
        out += list(spellings) + [p + spellings[0] for p in prefixes if p not in "\u00b5\u03bc"]
    return list(dict.fromkeys(unicodedata.normalize("NFKC", u) for u in out))  # the ohm sign is shown as omega


def convert(value: float, from_unit: str, to_unit: str) -> float:
    """``value`` in ``from_unit`` expressed in ``to_unit``; UnitError if their dimensions differ."""
    a, b = parse_unit(from_unit), parse_unit(to_unit)
    if a.signature != b.signature:
        raise UnitError(f"cannot convert {from_unit} ({a.dimension_text}) to {to_unit} ({b.dimension_text})")
    return b.from_base(a.to_base(value))


def channel_conversion(name: str, unit: str) -> tuple[float, float]:
    """(factor, offset) taking values of channel ``name`` given in ``unit`` to its stored unit.

    ``unit`` "" means the stored unit. Raises UnitError naming the allowed units when the
    unit is not one of the channel's dimension (``load`` also takes g, kg, mg).
    """
    ch = CHANNELS[name]
    if unit in ("", ch.unit):
        return 1.0, 0.0
    allowed = units_of(ch.dimension) + (units_of("mass") if name == "load" else [])
    hit = _lookup(unit)
    if hit is None or hit[0] not in (ch.dimension, "mass" if name == "load" else ch.dimension):
        raise UnitError(f"unit '{unit}' is not a unit of {ch.dimension} for {name}; use one of: {', '.join(allowed)}")
    dim, f, o = hit
    if dim == "mass":  # a hanging mass given for the load column: g -> N
        return f * 1e-3 * G0_M_PER_S2 / DIMENSIONS["force"][ch.unit][0], 0.0
    sf, so = DIMENSIONS[ch.dimension][ch.unit]
    return f / sf, (o - so) / sf
