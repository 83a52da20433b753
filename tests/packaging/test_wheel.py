"""The built wheel, installed into a fresh virtual environment, runs the README's first
command from outside the source tree (the shipped configs come with it)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _first_readme_command() -> list[str]:
    """The `tsa-bench ...` part of the README's first set-up command."""
    text = (ROOT / "README.md").read_text()
    block = re.search(r"```sh\n(.*?)\n```", text, re.S).group(1)
    return next(part for part in block.split("&&") if part.strip().startswith("tsa-bench")).split()


def test_the_installed_wheel_runs_the_first_readme_command(tmp_path):
    src = tmp_path / "src"
    for name in ("host", "configs"):
        shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info", "*.pyc"))
    for name in ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md"):
        shutil.copy(ROOT / name, src / name)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PIP_REQUIRE_VIRTUALENV")}
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    dist = tmp_path / "dist"
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-w", str(dist),
                            str(src)], capture_output=True, text=True, env=env, timeout=300)
    assert built.returncode == 0, built.stdout[-3000:] + built.stderr[-3000:]
    (wheel,) = dist.glob("tsa_bench-*.whl")
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", str(venv)], check=True,
                   timeout=120)
    python = venv / "bin" / "python"
    installed = subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps",
                                "--no-index", str(wheel)], capture_output=True, text=True, env=env, timeout=300)
    assert installed.returncode == 0, installed.stdout[-3000:] + installed.stderr[-3000:]
    shutil.rmtree(src)                           # nothing of a source tree is left to lean on
    work = tmp_path / "elsewhere"
    work.mkdir()
    where = subprocess.run([str(python), "-c", "import tsa_bench.shipped as s; print(s.__file__); "
                            "print(s.configs_root())"], capture_output=True, text=True, cwd=work, env=env)
    module, configs = where.stdout.split()
    assert module.startswith(str(venv)) and configs.startswith(str(venv)), where.stdout + where.stderr
    command = _first_readme_command()
    assert command[:2] == ["tsa-bench", "run"]
    res = subprocess.run([str(venv / "bin" / command[0]), *command[1:]], capture_output=True, text=True, cwd=work,
                         env=env, timeout=600)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    written = list((work / "runs").glob("*.h5"))
    assert len(written) == 1 and "exit status  success" in res.stdout
    assert "using the shipped" in res.stderr
    # the firmware is not in a wheel: the simavr bench says so, and what works without it (issue 35, defect 8)
    fil = subprocess.run([str(venv / "bin" / "tsa-bench"), "run", command[2], "--bench", "simavr.yaml"],
                         capture_output=True, text=True, cwd=work, env=env, timeout=300)
    assert fil.returncode == 2, fil.stdout[-3000:] + fil.stderr[-3000:]
    assert "installed without the firmware" in fil.stderr and "source checkout" in fil.stderr
    assert "simulated bench" in fil.stderr and "--trust-firmware-dir" not in fil.stderr
