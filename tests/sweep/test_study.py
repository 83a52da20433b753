"""Study files: validation with file:line before anything runs, point expansion, point keys."""

from __future__ import annotations

from pathlib import Path

import pytest

from tsa_bench.userfiles import DocumentError
from tsa_bench.sweep import load_study

GOOD = """\
study: tiny
runner: simulate
seed: 3
base:
  protocol: {shape: lifetime, cycles: 2}
vary:
  plant.effects.resistance_creep.ohm_per_turn: [0, 2.0e-5]
  protocol.cycles: {grid: {start: 2, stop: 6, step: 2}}
  bench.seed: {random: {low: 0, high: 1000, count: 2}}
"""


def write(tmp_path: Path, text: str, name: str = "study.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def refused(tmp_path: Path, text: str) -> DocumentError:
    with pytest.raises(DocumentError) as info:
        load_study(write(tmp_path, text))
    return info.value


def test_points_are_the_product_of_the_axes(tmp_path):
    s = load_study(write(tmp_path, GOOD))
    assert len(s.points) == 2 * 3 * 2
    assert [p.index for p in s.points] == list(range(12))
    cycles = sorted({p.config["protocol"]["cycles"] for p in s.points})
    assert cycles == [2, 4, 6] and all(isinstance(c, int) for c in cycles)
    p = s.points[-1]
    assert p.config["plant"]["effects"]["resistance_creep"]["ohm_per_turn"] == 2e-5
    assert p.varied == {"plant.effects.resistance_creep.ohm_per_turn": 2e-5, "protocol.cycles": 6,
                        "bench.seed": p.config["bench"]["seed"]}
    assert len({p.key for p in s.points}) == 12


def test_random_draws_are_seeded_and_keys_stable(tmp_path):
    a, b = load_study(write(tmp_path, GOOD, "a.yaml")), load_study(write(tmp_path, GOOD, "b.yaml"))
    assert [p.key for p in a.points] == [p.key for p in b.points]
    seeds = {p.config["bench"]["seed"] for p in a.points}
    assert len(seeds) == 2 and all(0 <= s <= 1000 for s in seeds)
    other = load_study(write(tmp_path, GOOD.replace("seed: 3", "seed: 4"), "c.yaml"))
    assert {p.config["bench"]["seed"] for p in other.points} != seeds


def test_key_changes_with_the_configuration_and_the_version(tmp_path, monkeypatch):
    import tsa_bench.sweep.study as study_mod

    base = load_study(write(tmp_path, GOOD)).points[0].key
    changed = load_study(write(tmp_path, GOOD.replace("cycles: 2}", "cycles: 2, load_g: 500}"), "d.yaml"))
    assert changed.points[0].key != base
    monkeypatch.setattr(study_mod, "__version__", "99.0.0")
    assert load_study(write(tmp_path, GOOD, "e.yaml")).points[0].key != base


@pytest.mark.parametrize("line, replacement, where, words", [
    ("  protocol.cycles: {grid: {start: 2, stop: 6, step: 2}}", "  protocol.cycels: [1, 2]", ":8:", "cycels"),
    ("  plant.effects.resistance_creep.ohm_per_turn: [0, 2.0e-5]",
     "  plant.effects.resistance_creep.ohms: [0, 1]", ":7:", "no parameter 'ohms'"),
    ("  plant.effects.resistance_creep.ohm_per_turn: [0, 2.0e-5]",
     "  plant.effects.resistence_creep.ohm_per_turn: [0, 1]", ":7:", "unknown plant effect"),
    ("  protocol.cycles: {grid: {start: 2, stop: 6, step: 2}}", "  protocol.cycles: []", ":8:", "empty"),
    ("  protocol.cycles: {grid: {start: 2, stop: 6, step: 2}}",
     "  protocol.cycles: {grid: {start: 2, stop: 6, num: 0}}", ":8:", "empty"),
    ("  protocol.cycles: {grid: {start: 2, stop: 6, step: 2}}",
     "  protocol.cycles: {grid: {start: 6, stop: 2, step: 1}}", ":8:", "empty"),
    ("  protocol: {shape: lifetime, cycles: 2}", "  protocol: {shape: lifetime, hold_s: 2}", ":5:", "hold_s"),
    ("  protocol.cycles: {grid: {start: 2, stop: 6, step: 2}}", "  protocol.cycles: [2, 2.5]", ":8:",
     "integer"),
    ("  bench.seed: {random: {low: 0, high: 1000, count: 2}}", "  bench.preset: [sim, no-such]", ":9:",
     "must be one of"),
    ("runner: simulate", "runner: simulat", ":2:", "runner must be one of"),
])
def test_bad_study_is_refused_with_file_line(tmp_path, line, replacement, where, words):
    assert line in GOOD
    err = refused(tmp_path, GOOD.replace(line, replacement))
    assert str(err).startswith(str(tmp_path / "study.yaml") + where), str(err)
    assert words in str(err)
    assert "\n" not in str(err)


def test_diagnose_clean_points_collapse_to_one(tmp_path):
    s = load_study(write(tmp_path, """\
study: power
runner: diagnose
vary:
  effect.name: [resistance_creep, length_creep]
  effect.magnitude: [0, 1.0]
"""))
    assert len(s.points) == 3
    clean = [p for p in s.points if p.config["effect"]["name"] == "none"]
    assert len(clean) == 1 and clean[0].config["effect"]["magnitude"] == 0.0


def test_report_lines_must_be_varied(tmp_path):
    err = refused(tmp_path, GOOD + "report: {lines: [bench.preset]}\n")
    assert f"{tmp_path / 'study.yaml'}:10:" in str(err) and "not a varied parameter" in str(err)
    ok = load_study(write(tmp_path, GOOD + "report: {lines: [protocol.cycles]}\n", "ok.yaml"))
    assert ok.lines == ["protocol.cycles"]
