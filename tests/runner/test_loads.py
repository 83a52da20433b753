"""Loads: declared loads reach the simulated plant and the run file; undeclared ones stay unknown."""

from __future__ import annotations

import h5py
import numpy as np

from tests.runner.helpers import open_sim, plan_from_text, run_plan

G = 9.80665e-3


def test_declared_loads_are_applied_and_recorded(tmp_path):
    plan = plan_from_text("""name: loads
load_g: 200
steps:
  - hold: {duration_s: 5}
  - prompt: {text: "hang 600 g", load_g: 600}
  - hold: {duration_s: 5}
""")
    port = open_sim()
    stop, client, path = run_plan(plan, tmp_path, port=port)
    assert stop.exit_status == "success"
    assert port.device.plant.load_g == 600
    with h5py.File(path) as f:
        load, length, seg = f["samples/load"][()], f["samples/length"][()], f["samples/segment"][()]
    assert np.allclose(load[seg == 0], 200 * G) and np.allclose(load[seg == 2], 600 * G)
    assert length[seg == 2].mean() > length[seg == 0].mean() + 5  # compliant strings stretch


def test_undeclared_load_is_nan_and_left_alone(tmp_path):
    plan = plan_from_text("name: noload\nsteps:\n  - hold: {duration_s: 3}\n")
    port = open_sim()
    before = port.device.plant.load_g
    stop, client, path = run_plan(plan, tmp_path, port=port)
    assert stop.exit_status == "success" and port.device.plant.load_g == before
    with h5py.File(path) as f:
        assert np.all(np.isnan(f["samples/load"][()]))
