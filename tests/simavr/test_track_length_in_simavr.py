"""track_length on the firmware in simavr: the same step, runner and estimator as on the
simulated bench, through the real firmware's queue, DWELLs and CS5513 readout."""

from __future__ import annotations

import subprocess
import sys

import yaml

from tsa_bench.control.evaluation import target_figures
from tsa_bench.store.reader import read_run

PROTOCOL = """name: track-length-simavr
load_g: 250
sampling_period_s: 0.1
limits: {{max_twist_turns: 55, max_heater_voltage_V: 0}}
defaults: {{rate_turns_per_s: 3.33, accel_turns_per_s2: 50}}
steps:
  - hold: {{duration_s: 5}}
  - move_to: {{turns: 30}}
  - hold: {{duration_s: 10}}
  - track_length: {{model: {model}, length_mm: 203, hold_s: 5}}
  - move_to: {{turns: 0}}
  - heater: {{voltage_V: 0}}
"""


def test_track_length_runs_on_the_firmware_to_success(repo_root, firmware_dir, tmp_path):
    # the emulated rig with the Scheme 2 string (the plant and the name the model was fitted for)
    bench = yaml.safe_load((repo_root / "configs/bench/simavr.yaml").read_text())
    scheme2 = yaml.safe_load((repo_root / "configs/bench/sim-scheme2-4ply.yaml").read_text())
    bench["plant"], bench["name"] = scheme2["plant"], scheme2["name"]
    bench["simavr"]["firmware_dir"] = str(firmware_dir)
    bench_file = tmp_path / "simavr-scheme2.yaml"
    bench_file.write_text(yaml.safe_dump(bench))
    protocol = tmp_path / "track.yaml"
    protocol.write_text(PROTOCOL.format(model=repo_root / "configs/models/scheme2-self-sensing.json"))
    out = tmp_path / "run.h5"
    result = subprocess.run([sys.executable, "-m", "tsa_bench.cli", "run", str(protocol), "--bench", str(bench_file),
                             "--seed", "3", "--output", str(out)], cwd=repo_root, capture_output=True, text=True,
                            timeout=1200)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert "violations: none" in result.stdout
    run = read_run(out)
    assert run.attrs["backend"] == "simavr" and run.exit_status == "success"
    assert int(run.attrs["samples_lost"]) == 0
    (fig,) = target_figures(run)
    assert fig.rise_s is not None, "the target was reached"
    assert abs(fig.steady_error_mm) <= 0.5, fig
