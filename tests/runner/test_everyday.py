"""The rough edges a lab user hits on day one, each fixed: the bench file a serial port
gets, options that mean nothing to a real device, the path printed first, resistance
'not measured' while heating, flash on an absent port, every bench-file error at once,
ls and info on several files, and start-up that loads click alone."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from rich.console import Console

from tsa_bench.cli import main
from tsa_bench.console.progress import ProgressDisplay
from tsa_bench.rundocs import SAMPLE_COLUMNS, SampleBlock
from tsa_bench.shipped import configs_root, find_config

ROOT = Path(__file__).resolve().parents[2]
SHORT = """name: short
steps:
  - move_to: {turns: 5, rate_turns_per_s: 2, accel_turns_per_s2: 20}
  - hold: {duration_s: 5}
"""


def _short(tmp_path) -> Path:
    p = tmp_path / "short.yaml"
    p.write_text(SHORT)
    return p


@pytest.mark.parametrize("extra,part", [
    (["--port", "/dev/ttyACM7", "--speed", "2"], "--speed applies only to a simulated bench"),
    (["--port", "/dev/ttyACM7", "--seed", "3"], "--seed applies only to a simulated bench"),
    (["--bench", str(ROOT / "configs/bench/arduino-mega.yaml"), "--seed", "3"], "the device on /dev/ttyACM0"),
])
def test_simulation_options_are_refused_for_a_serial_device(tmp_path, extra, part):
    res = CliRunner().invoke(main, ["run", str(_short(tmp_path)), "--out", str(tmp_path / "o"), *extra])
    assert res.exit_code == 2 and part in res.output and "no --bench given" not in res.output.split("error")[1]
    assert not (tmp_path / "o").exists() or not list((tmp_path / "o").iterdir())


def test_a_port_alone_validates_with_the_mega_bench(tmp_path):
    res = CliRunner().invoke(main, ["validate", str(_short(tmp_path)), "--port", "/dev/ttyACM7"])
    assert res.exit_code == 0, res.output
    assert "using the Arduino Mega bench file" in res.output and "valid for bench 'Arduino Mega 2560" in res.output


def test_a_real_device_never_gets_a_simulated_bench_file(tmp_path, monkeypatch):
    """A device without the SIMULATED flag (real hardware) and a bench file with a plant:
    refused after the handshake, before anything moves or any file is written."""
    from tsa_bench.device import client as client_module

    connect = client_module.BenchClient.connect

    def as_real_hardware(self, *a, **kw):
        ident = connect(self, *a, **kw)._replace(flags=0)
        self.identity = ident
        return ident

    monkeypatch.setattr(client_module.BenchClient, "connect", as_real_hardware)
    out = tmp_path / "x.h5"
    res = CliRunner().invoke(main, ["run", str(_short(tmp_path)), "--bench", str(ROOT / "configs/bench/sim.yaml"),
                                    "--port", "sim://", "--output", str(out)])
    assert res.exit_code == 2 and "is real hardware: use a serial bench file" in res.output
    assert not out.exists()


def test_run_says_where_it_writes_before_it_starts(tmp_path):
    out = tmp_path / "r.h5"
    res = CliRunner().invoke(main, ["run", str(_short(tmp_path)), "--output", str(out), "--meta", "operator=ana",
                                    "--meta", "sample=S3, batch 2"])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert lines[1] == f"run file     {out}   (live view: tsa-bench watch {out})"
    import h5py
    import json
    with h5py.File(out) as f:
        assert json.loads(f.attrs["metadata"]) == {"operator": "ana", "sample": "S3, batch 2"}


def test_progress_shows_not_measured_while_heating():
    shown = ProgressDisplay(Console(file=open(os.devnull, "w"), force_terminal=False))
    n = 3
    cols = {name: np.zeros(n, dtype=dtype) for name, (dtype, _) in SAMPLE_COLUMNS.items()}
    cols["resistance"] = np.array([5.1, np.nan, np.nan])
    cols["heater_voltage"] = np.array([0.0, 3.0, 3.0])
    shown.on_samples(SampleBlock(cols))
    text = shown.__rich__().plain
    assert "R not measured (heater on)" in text and "5.1" not in text
    cols["resistance"], cols["heater_voltage"] = np.array([5.2, 5.2, 5.25]), np.zeros(3)
    shown.on_samples(SampleBlock(cols))
    assert "R   5.2500 ohm" in shown.__rich__().plain


def test_flash_fails_at_once_on_an_absent_port(tmp_path):
    t0 = time.monotonic()
    res = subprocess.run(["make", "-C", str(ROOT / "firmware"), "flash", f"PORT={tmp_path / 'ttyACM9'}"],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode != 0 and "is not a serial device" in res.stderr and "tsa-bench ports" in res.stderr
    assert "avrdude" not in res.stdout and "avr-g++" not in res.stdout   # it built and tried nothing
    assert time.monotonic() - t0 < 60


def test_every_bench_file_error_at_once_with_its_position(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nbackend: serial\nbogus: 1\nsteps_per_turn: 3200\n"
                   "limits: {max_twist_turns: 10, max_speed: 3}\n"
                   "position_sensor: {mm_per_count: abc, offset_mm: 1}\n"
                   "resistance_sensor: {sense_current_A: -1, vref_V: 2.5}\nbaud: fast\n")
    res = CliRunner().invoke(main, ["validate", str(_short(tmp_path)), "--bench", str(bad)])
    assert res.exit_code == 2 and "Traceback" not in res.output and "__init__" not in res.output
    lines = [ln.removeprefix("error: ") for ln in res.output.splitlines()]
    lines = [ln for ln in lines if ln.startswith(str(bad))]
    assert [ln.split(": ")[1] for ln in lines] == ["bogus", "limits.max_speed", "position_sensor.mm_per_count",
                                                   "resistance_sensor.sense_current_A", "baud"]
    assert lines[1].startswith(f"{bad}:5:") and lines[-1].startswith(f"{bad}:8:")


def test_ls_and_info_on_several_files(tmp_path):
    runs = tmp_path / "runs"
    for name in ("a", "b"):
        assert CliRunner().invoke(main, ["run", str(_short(tmp_path)), "--output", str(runs / f"{name}.h5")]
                                  ).exit_code == 0
    (runs / "junk.h5").write_bytes(b"not hdf5")
    res = CliRunner().invoke(main, ["ls", str(runs)])
    assert res.exit_code == 0, res.output
    rows = res.output.splitlines()
    assert rows[1].startswith("success") and rows[1].endswith("a.h5") and "2/2" in rows[1] and "short" in rows[1]
    assert rows[3].startswith("?") and "junk.h5" in rows[3] and "not a readable HDF5 file" in rows[3]
    res = CliRunner().invoke(main, ["info", str(runs / "a.h5"), str(runs / "junk.h5"), str(runs / "b.h5")])
    assert res.exit_code == 2 and res.output.count("exit status  success") == 2 and "junk.h5" in res.output


def _loaded(*args: str) -> set[str]:
    """Top-level modules a CLI call imports (python -X importtime)."""
    res = subprocess.run([sys.executable, "-X", "importtime", "-m", "tsa_bench.cli", *args], capture_output=True,
                         text=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT / "host")})
    return {line.split("|")[-1].strip() for line in res.stderr.splitlines() if line.startswith("import time:")}


def test_start_up_loads_only_what_a_command_needs(tmp_path):
    heavy = {"numpy", "scipy", "matplotlib", "h5py", "yaml", "serial", "rich"}
    for args in (["--version"], ["--help"], ["run", "--help"]):
        assert not (heavy & _loaded(*args)), args
    out = tmp_path / "r.h5"
    assert CliRunner().invoke(main, ["run", str(_short(tmp_path)), "--output", str(out)]).exit_code == 0
    for args in (["info", str(out)], ["validate", str(_short(tmp_path))], ["ls", str(tmp_path)]):
        assert not ({"scipy", "matplotlib"} & _loaded(*args)), args


def test_shipped_configs_are_found_from_anywhere(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ("configs/protocols/lifetime.yaml", "protocols/lifetime.yaml", "lifetime", "lifetime.yaml"):
        found, shipped = find_config(name, "protocols")
        assert shipped and found == configs_root() / "protocols" / "lifetime.yaml", name
    assert find_config("nothere.yaml", "protocols") == (Path("nothere.yaml"), False)
    assert find_config("../configs/protocols/lifetime.yaml", "protocols")[1] is True   # only its name is used
    (tmp_path / "lifetime.yaml").write_text("a local file wins")
    assert find_config("lifetime.yaml", "protocols") == (Path("lifetime.yaml"), False)
    res = CliRunner().invoke(main, ["validate", "configs/protocols/lifetime.yaml", "--bench", "sim-4ply"])
    assert res.exit_code == 0, res.output
    assert "using the shipped" in res.output and "valid for bench" in res.output
