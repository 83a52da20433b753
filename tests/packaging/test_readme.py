"""The README's set-up: exactly two commands (the main job, the tests), a virtual
environment and the Python version named, and .ci/run running the README's test command."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _setup_commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    section = text.split("## Set up", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```sh\n(.*?)\n```", section, re.S), section


def test_two_setup_commands_in_a_venv_and_ci_runs_the_test_one():
    commands, section = _setup_commands()
    assert len(commands) == 2 and all("\n" not in c for c in commands)
    main, tests = commands
    for command in commands:   # a fresh Debian/Ubuntu refuses a system-wide pip install
        assert command.index("python3 -m venv .venv") < command.index(". .venv/bin/activate") \
            < command.index("pip install")
    assert main.rstrip().split("&&")[-1].strip().startswith("tsa-bench run ")
    assert tests.rstrip().endswith("python -m pytest") and '".[dev]"' in tests
    assert "Python 3.11 or newer" in section
    ci = (ROOT / ".ci" / "run").read_text()
    assert tests in ci.splitlines()
