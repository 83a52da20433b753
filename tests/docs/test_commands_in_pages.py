"""Every ``tsa-bench`` command line the pages show (docs/**/*.md and README.md, in code
blocks and inline code) names a command that exists and only options that command has."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import click

from tsa_bench.cli import main

ROOT = Path(__file__).resolve().parents[2]
PAGES = sorted((ROOT / "docs").rglob("*.md")) + [ROOT / "README.md"]


def _command_lines(text: str) -> list[str]:
    lines = []
    for body in re.findall(r"^```\w*\n(.*?)^```", text, re.S | re.M):
        for line in body.replace("\\\n", " ").splitlines():
            line = line.strip().removeprefix("$ ")
            if line.startswith("tsa-bench "):
                lines.append(line)
    prose = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    return lines + re.findall(r"`(tsa-bench [^`]+)`", prose)


def _unknown(line: str) -> list[str]:
    """What ``line`` names that the command line does not have."""
    words = shlex.split(line, comments=True)
    ctx = click.Context(main)
    cmd: click.Command = main
    i = 1
    while isinstance(cmd, click.Group) and i < len(words) and not words[i].startswith("-"):
        sub = cmd.get_command(ctx, words[i])
        if sub is None:
            # a placeholder (COMMAND) stands for any command
            return [] if words[i].isupper() else [f"no command {words[i]!r} in {cmd.name}"]
        cmd, i = sub, i + 1
    options = {o for p in cmd.params for o in (*p.opts, *p.secondary_opts)} | {"--help", "--version"}
    return [f"{cmd.name} has no option {w.split('=')[0]}" for w in words[i:]
            if w.startswith("--") and len(w) > 2 and w.split("=")[0] not in options]


def test_every_command_line_on_the_pages_exists():
    found, wrong = 0, []
    for page in PAGES:
        for line in _command_lines(page.read_text(encoding="utf-8")):
            found += 1
            wrong += [f"{page.relative_to(ROOT)}: {line}: {why}" for why in _unknown(line)]
    assert not wrong, "\n".join(wrong)
    assert found >= 100, found        # the pages are full of commands: the search finds them


def test_a_wrong_command_or_option_is_found():
    assert _unknown("tsa-bench calibrate position --at-turns 0,20") == []
    assert _unknown("tsa-bench calibrate position --at-turn 0,20") == ["position has no option --at-turn"]
    assert _unknown("tsa-bench imports x.csv") == ["no command 'imports' in main"]
