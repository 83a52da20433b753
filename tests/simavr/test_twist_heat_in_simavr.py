"""twist_heat on the firmware in simavr: the heater levels and sub-moves are plain queued
SET_HEATER and MOVE_TO commands, so the unchanged firmware applies each level during its sub-move."""

from __future__ import annotations

import subprocess
import sys

import yaml

from tests.plan.test_twist_heat_step import BACKEND_PROTOCOL, check_heater_during_sub_moves
from tsa_bench.store.reader import read_run


def test_twist_heat_runs_on_the_firmware_with_each_level_during_its_sub_move(repo_root, firmware_dir, tmp_path):
    bench = yaml.safe_load((repo_root / "configs/bench/simavr.yaml").read_text())
    bench["simavr"]["firmware_dir"] = str(firmware_dir)
    bench_file = tmp_path / "simavr.yaml"
    bench_file.write_text(yaml.safe_dump(bench))
    protocol = tmp_path / "twist-heat.yaml"
    protocol.write_text(BACKEND_PROTOCOL)
    out = tmp_path / "run.h5"
    result = subprocess.run([sys.executable, "-m", "tsa_bench.cli", "run", str(protocol), "--bench", str(bench_file),
                             "--output", str(out)], cwd=repo_root, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    run = read_run(out)
    assert run.attrs["backend"] == "simavr"
    check_heater_during_sub_moves(run)
