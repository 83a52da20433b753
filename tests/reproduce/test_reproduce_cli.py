"""`tsa-bench reproduce`: the side-by-side table, its verdicts and roles, JSON and figures (full and --quick)."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.reproduce.plan import load_plan
from tsa_bench.reproduce.records import load_records
from tsa_bench.reproduce.table import VERDICTS


def _run(*args: str) -> dict:
    res = CliRunner().invoke(main, ["reproduce", "--json", *args])
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout[res.stdout.index("{"):])


@pytest.fixture(scope="module")
def full():
    """The whole table as `tsa-bench reproduce` prints it (about a minute of simulated experiments)."""
    return _run(), None


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    figs = tmp_path_factory.mktemp("figs")
    return _run("--quick", "--figures", str(figs)), figs


@pytest.mark.parametrize("which", ["full", "quick"])
def test_every_record_gets_a_row_with_a_verdict_and_a_role(which, request):
    doc, _ = request.getfixturevalue(which)
    rows = {r["id"]: r for r in doc["rows"]}
    records = load_records()
    assert set(rows) == {r.id for r in records}
    plan = load_plan(records)
    for rec in records:
        row = rows[rec.id]
        assert row["verdict"] in VERDICTS and row["role"] == plan.role(rec.id)
        if rec.measure is None:
            assert row["verdict"] == "not simulated" and row["reason"] == rec.not_simulated
        else:
            assert row["verdict"] != "not computed", row
            assert row["simulated"] is not None and row["tolerance"], row


def test_built_from_records_are_never_counted_as_agreement(full):
    doc, _ = full
    built = [r for r in doc["rows"] if r["role"] == "built-from"]
    assert len(built) >= 10
    for r in built:
        assert r["verdict"] == "consistency-only" and "built from this number" in r["reason"], r
    assert "built-from" not in doc["summary"]["by_role"]  # not in the agreement counts at all


def test_every_compared_row_states_its_gap_and_every_disagreement_its_reason(full):
    doc, _ = full
    for r in doc["rows"]:
        if r["verdict"] in ("agrees", "disagrees"):
            assert r["gap"] is not None, r
        if r["verdict"] == "disagrees":
            assert r["reason"] and r["reason"] != "no reason named", r["id"]
    assert doc["summary"]["unexplained_disagreements"] == []
    # after calibration most held-out measured quantities agree; the tables' coefficients, which a
    # cubic or an over-parameterised model trades off against each other, mostly do not
    quantities = doc["summary"]["held_out_by_kind"]["quantity"]
    assert quantities["agrees"] > 1.4 * quantities["disagrees"]
    kinds = {r["kind"] for r in doc["rows"]
             if r["id"].startswith(("t3.1.3ply", "t3.2.s1", "t3.3.")) and r["verdict"] != "not simulated"}
    assert kinds == {"coefficient"}


def test_known_rows_after_calibration(full):
    rows = {r["id"]: r for r in full[0]["rows"]}
    assert rows["t3.3.b1"]["verdict"] == "consistency-only"  # the simulator's decay is Table 3.3's
    assert rows["ch4.control.rise_time"]["role"] == "fitted" and rows["ch4.control.rise_time"]["verdict"] == "agrees"
    assert rows["ch2.scheme2.range"]["verdict"] == "agrees"


def test_one_figure_per_chapter(quick):
    _, figs = quick
    names = sorted(p.name for p in figs.glob("*.png"))
    assert names == ["chapter2.png", "chapter3.png", "chapter4.png"]
    for p in figs.glob("*.png"):
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 20_000


def test_text_table_one_line_per_record_never_wrapped():
    res = CliRunner().invoke(main, ["reproduce", "--chapter", "4"])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    rec4 = [r for r in load_records() if r.chapter == 4]
    for rec in rec4:
        (line,) = [ln for ln in lines if ln.startswith(rec.id + " ")]
        assert len(line) > 100  # long rows stay on one line
    assert any(ln.startswith(f"{len(rec4)} records:") for ln in lines)
