"""Build hook: the wheel carries configs/ (bench presets, protocols, thesis data, every
file below it) as package data tsa_bench/_configs/, so an installed tsa-bench finds
them without the source tree (tsa_bench.shipped). Everything else is in pyproject.toml."""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent


class BuildWithConfigs(build_py):
    """build_py, then a copy of configs/** into the built package."""

    def run(self) -> None:
        super().run()
        if self.editable_mode:  # an editable install reads configs/ in the source tree
            return
        target = Path(self.build_lib) / "tsa_bench" / "_configs"
        if target.exists():
            shutil.rmtree(target)
        shutil.copytree(ROOT / "configs", target,
                        ignore=shutil.ignore_patterns("__pycache__", "*.pyc", ".*"))


setup(cmdclass={"build_py": BuildWithConfigs})
