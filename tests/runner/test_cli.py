"""The command line: run, validate, info, Ctrl-C, SIGKILL, and the pty bench."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.store import read_run
from tsa_bench.store.live import LiveTail, sidecar_path
from tsa_bench.store.recover import recover_run

ROOT = Path(__file__).resolve().parents[2]
PROTOCOLS = ROOT / "configs" / "protocols"
SHORT = """name: short
load_g: 300
steps:
  - move_to: {turns: 20, rate_turns_per_s: 2, accel_turns_per_s2: 20}
  - hold: {duration_s: 30}
  - prompt: {text: "hang 400 g", load_g: 400}
  - hold: {duration_s: 30}
  - move_to: {turns: 0, rate_turns_per_s: 2, accel_turns_per_s2: 20}
"""


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tsa_bench.cli", *args], capture_output=True, text=True, cwd=ROOT)


def test_run_writes_a_file_and_says_it_is_simulated(tmp_path):
    proto = tmp_path / "short.yaml"
    proto.write_text(SHORT)
    result = CliRunner().invoke(main, ["run", str(proto), "--out", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    first = result.output.splitlines()[0]
    assert "SIMULATED" in first
    files = list((tmp_path / "out").glob("*.h5"))
    assert len(files) == 1 and str(files[0]) in result.output
    with h5py.File(files[0]) as f:
        load = f["samples/load"][()]
        assert f.attrs["exit_status"] == "success"
    assert np.isclose(load.min(), 0.3 * 9.80665) and np.isclose(load.max(), 0.4 * 9.80665)
    info = CliRunner().invoke(main, ["info", str(files[0])])
    assert info.exit_code == 0 and "exit status  success" in info.output and "segments     5 recorded" in info.output


def test_invalid_protocol_exits_2_with_position_and_sends_nothing(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nsteps:\n  - hold: {duration_s: -3}\n")
    result = CliRunner().invoke(main, ["run", str(bad), "--port", "/dev/does-not-exist", "--out", str(tmp_path)])
    assert result.exit_code == 2
    assert "bad.yaml:3" in result.output and "duration_s" in result.output
    assert "nothing was sent" in result.output and not list(tmp_path.glob("*.h5"))
    assert CliRunner().invoke(main, ["validate", str(bad)]).exit_code == 2


def test_validate_prints_the_compiled_plan():
    result = CliRunner().invoke(main, ["validate", str(PROTOCOLS / "lifetime.yaml")])
    assert result.exit_code == 0
    assert "11,928" in result.output and "596" in result.output


def test_unreachable_port_says_what_to_check(tmp_path):
    result = CliRunner().invoke(main, ["run", str(PROTOCOLS / "lifetime.yaml"), "--port", "/dev/no-such-tty",
                                       "--out", str(tmp_path)])
    assert result.exit_code == 1 and "/dev/no-such-tty" in result.output and "port" in result.output


def test_info_on_a_missing_file():
    result = CliRunner().invoke(main, ["info", "/nonexistent/run.h5"])
    assert result.exit_code == 2 and "no such file" in result.output


def _wait_for_samples(path: Path, minimum: int, timeout_s: float = 30) -> int:
    """Watch a file that another process is writing (without HDF5's file lock)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with h5py.File(path, "r", locking=False) as f:
                n = len(f["samples/t"])
                if n >= minimum:
                    return n
        except (OSError, KeyError):
            pass
        time.sleep(0.2)
    raise AssertionError(f"no {minimum} samples in {path} after {timeout_s} s")


def _start_run(tmp_path: Path, speed: str) -> tuple[subprocess.Popen, Path]:
    out = tmp_path / "run.h5"
    env = {k: v for k, v in os.environ.items() if k != "HDF5_USE_FILE_LOCKING"}
    proc = subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", "run", str(PROTOCOLS / "lifetime.yaml"),
                             "--output", str(out), "--speed", speed], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return proc, out


def test_sigkill_leaves_a_readable_file_and_a_journal_that_finishes_it(tmp_path):
    """Killed: the file opens as it is with plain h5py (whole rows of the whole chunks it
    stored); its journal holds every sample and segment row after those, and recovery (what
    `run --resume` does first) puts them into the file."""
    proc, out = _start_run(tmp_path, "400")
    try:
        _wait_for_samples(out, 200)
        time.sleep(1.5)
        proc.kill()
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    # a fresh process with default HDF5 settings (file locking on) must open it as is
    check = subprocess.run([sys.executable, "-c", KILLED_FILE_CHECK, str(out)], capture_output=True, text=True,
                           env={k: v for k, v in os.environ.items() if k != "HDF5_USE_FILE_LOCKING"})
    assert check.returncode == 0, check.stderr
    samples, segments = map(int, check.stdout.split())
    assert samples > 200
    tail = LiveTail(sidecar_path(out), documents=True)
    live = tail.poll()
    journaled = len(tail.segments)
    tail.close()
    assert len(live) >= samples and journaled > segments
    recover_run(out)
    run = read_run(out)
    assert len(run) == len(live) and len(run.segments) == journaled and run.exit_status == "failed"


KILLED_FILE_CHECK = """
import sys, h5py, numpy as np
with h5py.File(sys.argv[1], "r") as f:
    assert f.attrs["exit_status"] == "running", "killed: never closed"
    n = {len(ds) for ds in f["samples"].values()}
    assert len(n) == 1, n
    t = f["samples/t"][()]
    assert np.all(np.diff(t) > 0) and np.all(np.isfinite(f["samples/length"][()]))
    print(len(t), len(f["segments"]))
"""


def test_ctrl_c_stops_the_device_and_closes_the_file_as_aborted(tmp_path):
    proc, out = _start_run(tmp_path, "200")
    try:
        _wait_for_samples(out, 100)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, stderr
    with h5py.File(out, "r") as f:
        assert f.attrs["exit_status"] == "aborted" and "Ctrl-C" in f.attrs["reason"]
        kinds = [e["kind"] for e in f["events"][()]]
        assert b"stop_sent" in kinds and b"stopped" in kinds
        assert f["samples/heater_voltage"][-1] == 0
    assert "aborted" in stdout


def test_pty_bench_end_to_end(tmp_path):
    """sim-serve on a pseudo-terminal, driven through pyserial's real Serial class."""
    proto = tmp_path / "short.yaml"
    proto.write_text(SHORT)
    server = subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", "sim-serve"], cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        pty_path = server.stdout.readline().strip()
        assert pty_path.startswith("/dev/"), pty_path
        result = cli("run", str(proto), "--port", pty_path, "--output", str(tmp_path / "pty.h5"))
        assert result.returncode == 0, result.stderr + result.stdout
        assert pty_path in result.stdout.splitlines()[0]
        with h5py.File(tmp_path / "pty.h5") as f:
            # a simulated device, even over a serial line; no --bench: the Mega bench file, no plant stored
            assert f.attrs["exit_status"] == "success" and f.attrs["backend"] == "sim"
            assert "plant" not in f["config/bench"][()].decode()
            assert len(f["segments"]) == 5 and len(f["samples/t"]) > 500
        assert "no --bench given for the serial port" in result.stderr and "arduino-mega.yaml" in result.stderr
    finally:
        server.send_signal(signal.SIGINT)
        try:
            server.wait(10)
        except subprocess.TimeoutExpired:
            server.kill()


def test_effects_lists_every_effect_with_units_and_bench_values():
    from tsa_bench.sim.effects import EFFECTS

    result = CliRunner().invoke(main, ["effects"])
    assert result.exit_code == 0
    for name in EFFECTS:
        assert f"{name}  (" in result.output
    assert "stiffness_N" in result.output and " N " in result.output
    scheme1 = CliRunner().invoke(main, ["effects", "--bench", str(ROOT / "configs" / "bench" / "sim-scheme1.yaml")])
    assert scheme1.exit_code == 0 and "(default 31.88)" in scheme1.output and "[on]" in scheme1.output


def test_unwritable_output_is_refused_before_anything_runs(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    result = CliRunner().invoke(main, ["run", str(PROTOCOLS / "lifetime.yaml"), "--out", str(blocker / "sub")])
    assert result.exit_code == 2 and "cannot write the run file" in result.output and "nothing was run" in result.output


def test_info_reads_a_killed_run(tmp_path):
    proc, out = _start_run(tmp_path, "400")
    try:
        _wait_for_samples(out, 50)
        proc.kill()
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    result = CliRunner().invoke(main, ["info", str(out)])
    assert result.exit_code == 0 and "exit status  running" in result.output


def test_an_existing_run_file_is_never_overwritten(tmp_path):
    existing = tmp_path / "precious.h5"
    existing.write_bytes(b"recorded data")
    result = CliRunner().invoke(main, ["run", str(PROTOCOLS / "lifetime.yaml"), "--output", str(existing)])
    assert result.exit_code == 2 and "already exists" in result.output
    assert existing.read_bytes() == b"recorded data"


def test_cli_model_names_match_the_library():
    from tsa_bench.cli.models import MODEL_NAMES as cli_names
    from tsa_bench.models.saved import MODEL_NAMES as lib_names

    assert tuple(cli_names) == tuple(lib_names)


def test_help_and_version_load_no_numerics():
    code = ("import sys; from tsa_bench.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
            "heavy = sorted(m for m in ('numpy', 'scipy', 'matplotlib', 'h5py') if m in sys.modules)\n"
            "print('HEAVY', heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         env={**os.environ, "PYTHONPATH": str(ROOT / "host")})
    assert "HEAVY []" in out.stdout, out.stdout + out.stderr
