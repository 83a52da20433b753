"""The thesis records (configs/thesis/) load, say where they come from, and bad record files are refused with file:line."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.reproduce.plan import load_plan
from tsa_bench.reproduce.records import RecordsError, load_records, record_files
from tsa_bench.units import parse_unit

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def records():
    return load_records()


def test_shipped_records_cover_the_thesis(records):
    ids = {r.id for r in records}
    assert len(records) >= 200 and len(ids) == len(records)
    assert {r.chapter for r in records} == {2, 3, 4}
    # Tables 3.1-3.3 in full, every error table of chapter 3, the strains of 2.4, the lifetime of 2.5.2
    assert sum(r.id.startswith("t3.1.") and r.id[-3:-1] == ".p" for r in records) == 48
    assert sum(r.id.startswith("t3.2.") and r.id[-3:-1] == ".p" for r in records) == 32
    assert sum(".curve." in r.id and bool(r.derived) for r in records) == 16  # the tables again, as curves
    assert sum(r.id.startswith("t3.3.") for r in records) == 15
    assert sum(r.id.startswith("s3.2.2.") and (".sr." in r.id or ".ss." in r.id) for r in records) == 28
    for needed in ("ch2.strain.3ply_200g_passive", "ch2.strain.3ply_200g_active", "ch2.strain.3ply_avg_active",
                   "ch2.strain.4ply_avg_passive", "ch2.strain.4ply_250g_thermal", "ch2.lifetime.duration",
                   "ch2.scheme1.length_20turns", "ch2.scheme2.range", "ch4.control.rise_time", "ch4.manip.model_error",
                   "ch4.control.sse_mean", "ch4.manip.vel.conventional.mean"):
        assert needed in ids, needed
    by = {r.id: r for r in records}
    assert by["ch2.strain.4ply_250g_thermal"].reading  # the ambiguous 14.1 % states the reading chosen
    assert by["ch2.scheme2.range"].range == (2.0, 3.0)
    assert by["f3.1a.twist.preisach.e_aver"].uncertainty == {"sd": 0.0346}


def test_every_record_has_a_source_unit_and_a_way_to_judge_it(records):
    for r in records:
        assert r.source["section"], r.id
        parse_unit(r.unit)
        assert (r.measure is None) != (r.not_simulated is None), r.id
        if r.measure is not None and r.relation in ("=", "~") and r.range is None:
            assert r.tolerance or r.uncertainty, r.id
        if r.tolerance:
            assert r.tolerance["basis"], r.id


def test_calibration_plan_names_existing_records(records):
    plan = load_plan(records)
    assert plan.fits and all(f.records for f in plan.fits)
    roles = {plan.role(r.id) for r in records}
    assert roles == {"built-from", "fitted", "held-out"}
    assert plan.role("t3.3.b1") == "built-from"  # the transient decay was typed in from Table 3.3


GOOD = """chapter: 2
records:
  - id: x.length
    quantity: a length
    value: 28
    unit: cm
    tolerance: {abs: 1, basis: read off}
    conditions: {scheme: 1, load_g: [450, 550], twist_turns: 20}
    source: {section: "2.5.1"}
    measure: {name: scheme_length, turns: 20}
"""

BAD = [
    (GOOD.replace("unit: cm", "unit: furlongs"), "rec.yaml:6:11", "unknown unit 'furlongs'"),
    (GOOD.replace("unit: cm", "unit: ohm"), "rec.yaml:6:11", "does not fit what scheme_length computes"),
    (GOOD.replace('    source: {section: "2.5.1"}\n', ""), "rec.yaml:3:5", "missing required key 'source'"),
    (GOOD.replace('source: {section: "2.5.1"}', 'source: {figure: "2.7"}'), "rec.yaml:9:13", "needs at least a 'section'"),
    (GOOD.replace("    tolerance: {abs: 1, basis: read off}\n", ""), "rec.yaml:3:5", "needs a tolerance or an uncertainty"),
    (GOOD.replace("name: scheme_length", "name: warp_factor"), "rec.yaml:10:14", "unknown measure 'warp_factor'"),
    (GOOD.replace("turns: 20}\n", "turns: 20, spin: 1}\n"), "rec.yaml:10:14", "unknown argument 'spin'"),
    (GOOD.replace("load_g: [450", "mass_kg: [450"), "rec.yaml:8:17", "unknown condition 'mass_kg'"),
    (GOOD + GOOD.split("records:\n")[1], "rec.yaml:11:9", "duplicate id 'x.length'"),
    (GOOD.replace("basis: read off", "basis: ''"), "rec.yaml:7:16", "needs a 'basis'"),
    ("chapter: 2\nrecords: [\n", "rec.yaml:3:1", "YAML syntax error"),
]


@pytest.mark.parametrize("text,where,what", BAD)
def test_bad_record_files_are_refused_with_file_line(tmp_path, text, where, what):
    path = tmp_path / "rec.yaml"
    path.write_text(text)
    with pytest.raises(RecordsError) as err:
        load_records([path])
    msg = str(err.value)
    assert where in msg and what in msg, msg


def test_a_good_record_file_loads(tmp_path):
    path = tmp_path / "rec.yaml"
    path.write_text(GOOD)
    (rec,) = load_records([path])
    assert rec.id == "x.length" and rec.value == 28 and rec.unit == "cm" and rec.line == 3
    assert rec.tolerance == {"kind": "abs", "value": 1.0, "basis": "read off"}


def test_reproduce_refuses_a_bad_record_directory_with_exit_2(tmp_path):
    (tmp_path / "rec.yaml").write_text(GOOD.replace("unit: cm", "unit: furlongs"))
    res = CliRunner().invoke(main, ["reproduce", "--records", str(tmp_path), "--plan", str(tmp_path / "none.yaml")])
    assert res.exit_code == 2 and "rec.yaml:6:11" in res.output and "furlongs" in res.output
    assert "Traceback" not in res.output
    empty = tmp_path / "empty"
    empty.mkdir()
    res = CliRunner().invoke(main, ["reproduce", "--records", str(empty)])
    assert res.exit_code == 2 and "no record files" in res.output


def test_record_files_exclude_the_plan():
    names = [p.name for p in record_files()]
    assert "calibration.yaml" not in names and len(names) == 4
