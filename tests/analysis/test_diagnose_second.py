"""`diagnose` on the second independent generator (tests/analysis/second): its own equations,
rigs, protocols and sampling rates, effects in forms the library does not have, sensor
artefacts a physical effect can mimic, effects outside the library.

Rates over a few seeds, each with its 95 % Wilson interval in the failure message; the
full matrix (at least 60 runs) is scripts/bench/diagnose_second.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.analysis.second.cases import judge, make, rates
from tests.analysis.second.rigs import RIGS, full_twist_turns, helix_length_mm, stretched_mm
from tsa_bench.analysis import diagnose, load_model
from tsa_bench.store import read_run

#: (case, seeds): clean rigs, library families in other forms, an artefact, effects outside the library
SMALL_N = [("clean-long", (1, 2)), ("clean-short", (3,)), ("power-transient", (1, 2)), ("r-gain-drift", (1, 2)),
           ("contact-ripple", (1, 2)), ("track-wave", (1,))]


def test_the_helix_solution_is_the_twisted_pair():
    rig = RIGS["mid-scp-uhmwpe"]
    ell = float(stretched_mm(rig, 600.0))
    assert helix_length_mm(rig, np.array([0.0]), 600.0)[0] == pytest.approx(ell, rel=1e-12)
    full = full_twist_turns(rig, 600.0)
    x = helix_length_mm(rig, np.linspace(0, full, 50), 600.0)
    assert np.all(np.diff(x) < 0) and x[-1] == pytest.approx(ell / np.sqrt(3.0), rel=1e-6)
    # the geometry it solves: l^2 = X^2 + (2 pi n r)^2 with r^2 X = r0^2 L0
    n = 0.6 * full
    xn = helix_length_mm(rig, np.array([n]), 600.0)[0]
    r = rig.radius_mm * np.sqrt(rig.untwisted_mm / xn)
    assert xn ** 2 + (2 * np.pi * n * r) ** 2 == pytest.approx(ell ** 2, rel=1e-9)


def test_rates_at_small_n(tmp_path):
    model = load_model(None)
    rows = []
    for name, seeds in SMALL_N:
        for seed in seeds:
            case = make(name, tmp_path / f"{name}-{seed}.h5", seed)
            rows.append(judge(case, diagnose([read_run(case.path)], model)))
    got = rates(rows)
    shown = {k: f"{v[0]}/{v[1]} (95 % {100 * v[2][0]:.0f}-{100 * v[2][1]:.0f} %)" for k, v in got.items()}
    detail = [(r["case"], r["named"], r["alternatives"], r["summary"][:160]) for r in rows]
    assert got["detection"][0] == got["detection"][1], (shown, detail)
    assert got["wrong name"][0] == 0 and got["false alarm"][0] == 0, (shown, detail)
    assert got["outside named with confidence > 0.5"][0] == 0, (shown, detail)
    # the artefact is named as what it is (a sensor drift), never as creep with confidence
    for r in rows:
        if r["case"] == "r-gain-drift":
            assert "resistance_sensor_drift" in r["named"] + r["alternatives"], r
