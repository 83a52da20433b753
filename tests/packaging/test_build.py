"""`python -m build` of a copy of the project, every warning an error: no deprecation in
the project metadata (issue 35: `project.license` as a TOML table was deprecated, with a
date after which such builds fail)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_the_build_passes_with_warnings_as_errors(tmp_path):
    src = tmp_path / "src"
    for name in ("host", "configs"):
        shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info", "*.pyc"))
    for name in ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md"):
        shutil.copy(ROOT / name, src / name)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONWARNINGS"] = "error"   # reaches the build backend's own process
    # no isolation: the setuptools of the [dev] extra (pyproject's build requirement), no download
    built = subprocess.run([sys.executable, "-m", "build", "--no-isolation", "--outdir", str(tmp_path / "dist"),
                            str(src)], capture_output=True, text=True, env=env, timeout=600)
    log = built.stdout + built.stderr
    assert built.returncode == 0, log[-4000:]
    assert "deprecat" not in log.lower(), log[-4000:]
    assert len(list((tmp_path / "dist").glob("tsa_bench-*.whl"))) == 1
    assert len(list((tmp_path / "dist").glob("tsa_bench-*.tar.gz"))) == 1
