"""The independent generator itself: its own code, its physics, its run files."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from tests.analysis.foreign import effects as fx
from tests.analysis.foreign.cases import CASES, make
from tests.analysis.foreign.plant import run_plant
from tests.analysis.foreign.rig import RIGS, full_twist_turns, stretched_mm, tsa_length_mm
from tests.analysis.foreign.walks import random_walk
from tsa_bench.store import read_run

FOREIGN = Path(__file__).parent / "foreign"


def test_generator_imports_nothing_of_the_project():
    for path in FOREIGN.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            for name in names:
                assert not name.startswith("tsa_bench"), f"{path.name} imports {name}"
                assert name.split(".")[0] in {"numpy", "scipy", "h5py", "tests", "__future__", "dataclasses",
                                              "collections", "json", "pathlib", "typing"}, (path.name, name)


@pytest.mark.parametrize("rig", RIGS.values(), ids=list(RIGS))
def test_kinematics_solve_the_cubic_and_clamp(rig):
    load = np.full(200, rig.loads_g[0])
    full = full_twist_turns(rig, rig.loads_g[0])
    turns = np.linspace(0.0, 1.3 * full, 200)
    x = tsa_length_mm(rig, turns, load)
    big_l = stretched_mm(rig, load)
    c = (2 * np.pi * turns) ** 2 * rig.radius_mm ** 2 * rig.untwisted_mm
    inside = turns < 0.999 * full
    assert np.allclose((x ** 3 - big_l ** 2 * x + c)[inside] / big_l[inside] ** 3, 0.0, atol=1e-9)
    assert np.all(np.diff(x) <= 1e-9) and x[0] == pytest.approx(big_l[0])
    assert np.allclose(x[turns > full], big_l[turns > full] / np.sqrt(3.0))


def test_walk_samples_at_the_rig_rate_and_changes_the_load():
    rig = RIGS["short-3ply"]
    h = random_walk(rig, seed=4, minutes=8)
    assert np.allclose(np.diff(h.t), 1.0 / rig.rate_hz)
    assert set(np.unique(h.load_g)) == set(rig.loads_g)
    assert h.moving.any() and (~h.moving.astype(bool)).any()
    assert np.all(np.diff(h.segment) >= 0)
    still = ~h.moving.astype(bool)
    assert np.all(np.diff(h.turns)[still[1:]] == 0)      # the twist changes only while moving


def test_forms_change_what_they_say():
    rig = RIGS["mid-4ply-12ohm"]
    h = random_walk(rig, seed=2, minutes=8)
    clean_l, clean_r = run_plant(rig, h, [], seed=1)
    slip_l, _ = run_plant(rig, h, [fx.SaturatingSlip(threshold_turns=float(h.turns.max()) * 0.5)], seed=1)
    assert np.nanmax(slip_l - clean_l) > 1.0                 # lost twist: longer
    _, tr_r = run_plant(rig, h, [fx.StretchedTransient(amp_ohm=0.05)], seed=1)
    assert np.all((tr_r - clean_r)[h.moving.astype(bool)] == 0) and np.nanmax(tr_r - clean_r) > 0.04
    ecc_l, ecc_r = run_plant(rig, h, [fx.Eccentricity(amplitude_mm=0.3)], seed=1)
    assert np.allclose(ecc_r, clean_r) and 0.2 < np.max(np.abs(ecc_l - clean_l)) <= 0.3 + 1e-9


def test_every_case_writes_a_contract_run_file(tmp_path):
    for name in ("clean-short-3ply", "foreign-contact-jumps"):
        case = make(name, tmp_path / f"{name}.h5", seed=1, minutes=4)
        run = read_run(case.path)
        assert len(run) == case.n and run.units["load"] == "N" and run.segments is not None
        assert case.verdict == CASES[name][2]
