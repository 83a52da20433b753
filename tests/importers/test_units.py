"""SI prefixes in exact case: M is mega and m milli, a spelling that could be either is refused naming both,
and the summary prints the factor applied (issue 29, item 1)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.importers.fixtures import run_import
from tsa_bench.store import read_run
from tsa_bench.units import DIMENSIONS, AmbiguousUnitError, UnitError, channel_conversion, parse_unit

# The expectations are written out here, not taken from units.py: prefix factors, and each unit's
# value in the dimension's base unit (mm, ohm, V, A, N, g, kPa, W, J, s, turn, 1).
SI = {"G": 1e9, "M": 1e6, "k": 1e3, "h": 1e2, "c": 1e-2, "m": 1e-3, "u": 1e-6, "\u00b5": 1e-6, "\u03bc": 1e-6,
      "n": 1e-9}
BASE_VALUE = {
    "resistance": {"ohm": 1.0, "Ohm": 1.0, "\u03a9": 1.0, "\u2126": 1.0},
    "voltage": {"V": 1.0}, "current": {"A": 1.0}, "force": {"N": 1.0, "lbf": 4.4482216152605},
    "mass": {"g": 1.0}, "power": {"W": 1.0}, "energy": {"J": 1.0},
    "pressure": {"Pa": 1e-3, "bar": 100.0, "psi": 6.894757293168, "ksi": 6894.757293168},
    "length": {"m": 1000.0, "in": 25.4},
    "time": {"s": 1.0, "min": 60.0, "h": 3600.0},
    "angle": {"turn": 1.0, "turns": 1.0, "rev": 1.0, "rotation": 1.0, "deg": 1 / 360, "\u00b0": 1 / 360,
              "rad": 1 / (2 * np.pi)},
    "dimensionless": {"1": 1.0, "%": 0.01, "ppm": 1e-6, "strain": 1.0},
}
CHANNEL_OF = {"resistance": "resistance", "voltage": "heater_voltage", "current": "current", "force": "force",
              "mass": "load", "pressure": "pressure", "length": "length", "time": "t", "angle": "turns",
              "dimensionless": "strain"}
STORED_IN = {"resistance": 1.0, "voltage": 1.0, "current": 1.0, "force": 1.0, "pressure": 1.0, "length": 1.0,
             "time": 1.0, "angle": 1.0, "dimensionless": 1.0}


def _expected(dim: str, spelling: str) -> float:
    """The spelling's value in the base unit, decomposed as [prefix] + unit by the tables above."""
    bases = BASE_VALUE[dim]
    if spelling in bases:
        return bases[spelling]
    prefix, rest = spelling[0], spelling[1:]
    assert prefix in SI and rest in bases, f"{spelling!r} ({dim}) is neither a unit nor a prefixed unit"
    return SI[prefix] * bases[rest]


CASES = [(dim, u) for dim, table in DIMENSIONS.items() if dim != "temperature" for u in table]


def test_every_prefix_and_unit_has_its_si_value():
    """The whole table: every accepted spelling (prefixed or not) of every dimension, against the SI values."""
    assert len(CASES) > 100
    wrong = []
    for dim, u in CASES:
        expected = _expected(dim, u)
        got = parse_unit(u)
        if got.signature != (() if dim == "dimensionless" else ((dim, 1),)) or not np.isclose(got.factor, expected,
                                                                                            rtol=1e-12):
            wrong.append((u, got.factor, expected))
        if dim in CHANNEL_OF:   # and as a column of that channel: the factor to its stored unit
            ch = CHANNEL_OF[dim]
            f, o = channel_conversion(ch, u)
            want = expected * 9.80665e-3 if dim == "mass" else expected / STORED_IN[dim]
            if not np.isclose(f, want, rtol=1e-12) or o:
                wrong.append((ch, u, f, want))
    assert not wrong


@pytest.mark.parametrize("prefix", ["G", "M", "k", "m", "u", "\u00b5"])
def test_mega_and_milli_are_never_folded_into_each_other(prefix):
    for base, dim in (("ohm", "resistance"), ("V", "voltage"), ("N", "force"), ("g", "mass"), ("Pa", "pressure")):
        u = prefix + base
        if u not in DIMENSIONS[dim]:
            continue
        assert np.isclose(parse_unit(u).factor, SI[prefix] * BASE_VALUE[dim][base])


@pytest.mark.parametrize("spelling,readings", [("MOHM", ("Mohm", "mohm")), ("MPA", ("MPa", "mPa")),
                                               ("mv", ("MV", "mV")), ("mn", ("MN", "mN"))])
def test_a_spelling_that_could_be_mega_or_milli_is_refused_naming_both(spelling, readings):
    with pytest.raises(AmbiguousUnitError) as exc:
        parse_unit(spelling)
    for r in readings:
        assert r in str(exc.value)
    assert "mega" in str(exc.value) and "milli" in str(exc.value)


def test_other_cases_with_one_reading_are_still_read():
    assert parse_unit("OHM").factor == 1.0 and parse_unit("Kohm").factor == 1e3
    assert parse_unit("MS").factor == 1e-3 and parse_unit("KPA").factor == 1.0
    with pytest.raises(UnitError):
        parse_unit("furlong")


@pytest.mark.parametrize("header,stored", [("R [MOhm]", 1.5e6), ("R_MOhm", 1.5e6), ("resistance [Mohm]", 1.5e6),
                                           ("resistance [mohm]", 1.5e-3), ("R [kohm]", 1.5e3)])
def test_megaohm_columns_are_stored_in_ohm_with_the_factor_printed(tmp_path, header, stored):
    res, out = run_import(tmp_path, f"t [s],length [mm],{header}\n0,100,1.5\n0.1,100.1,1.6\n")
    assert res.exit_code == 0, res.output
    assert np.isclose(read_run(out).samples["resistance"][0], stored, rtol=1e-12)
    assert f"-> ohm, x{stored / 1.5:g}]" in res.output


def test_millipascal_megavolt_meganewton_megagram_in_exact_case(tmp_path):
    res, out = run_import(tmp_path, "t [s],length [mm],p [mPa],heater_voltage [MV],force [MN],load [Mg]\n"
                                    "0,100,2,3e-6,1e-6,2e-4\n0.1,100,2,3e-6,1e-6,2e-4\n")
    assert res.exit_code == 0, res.output
    r = read_run(out)
    assert np.isclose(r.samples["pressure"][0], 2e-6)   # kPa
    assert np.isclose(r.samples["heater_voltage"][0], 3.0)
    assert np.isclose(r.samples["force"][0], 1.0)
    assert np.isclose(r.samples["load"][0], 200 * 9.80665e-3)
    assert "[mPa -> kPa, x1e-06]" in res.output and "[Mg -> N, x9806.65]" in res.output


def test_an_ambiguous_header_is_refused_and_units_says_which(tmp_path):
    text = "t [s],length [mm],R_MOHM\n0,100,1.5\n0.1,100.1,1.6\n"
    res, out = run_import(tmp_path, text)
    assert res.exit_code == 2 and not out.exists()
    assert "lab.csv:1: column 'R_MOHM' (resistance): unit 'MOHM' is ambiguous" in res.output
    assert "Mohm (mega, = 1e+06 ohm)" in res.output and "mohm (milli, = 0.001 ohm)" in res.output
    assert "--units resistance=" in res.output
    res, out = run_import(tmp_path, None, "--units", "resistance=Mohm", out="b.h5")
    assert res.exit_code == 0, res.output
    assert np.isclose(read_run(out).samples["resistance"][0], 1.5e6)
