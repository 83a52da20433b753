"""The shell sessions of docs/importing.md print what the page shows, where the page also
shows the input: a file made by ``printf`` or shown whole by ``cat`` in the same block, or
a command's ``# header: ...`` comment (the file is that header and three made-up rows:
time 0, 0.1, 0.2 in the first column, 100 in the others).

A shown output line must be a line of the command's output; ``...`` in it stands for any
text, a line of ``...`` alone for lines left out. A block's commands run in order in a
fresh folder; a command whose input the block does not show is not run.
"""

from __future__ import annotations

import re
import shlex
import subprocess
from pathlib import Path

from click.testing import CliRunner

from tsa_bench.cli import main

ROOT = Path(__file__).resolve().parents[2]


def _sessions(page: str) -> list[list[tuple[str, list[str]]]]:
    """Each ```text block of ``page`` holding a ``$`` command: its (command, shown output)."""
    text = (ROOT / "docs" / f"{page}.md").read_text(encoding="utf-8")
    out = []
    for block in re.findall(r"^```text\n(.*?)^```", text, re.S | re.M):
        steps: list[tuple[str, list[str]]] = []
        lines = iter(block.splitlines())
        for line in lines:
            if line.startswith("$ "):
                cmd = line[2:]
                while cmd.endswith("\\"):
                    cmd = cmd[:-1] + next(lines).strip()
                steps.append((cmd, []))
            elif steps:
                steps[-1][1].append(line)
        if steps:
            out.append(steps)
    return out


def _shown(line: str, output: list[str]) -> bool:
    pattern = ".*".join(re.escape(part) for part in line.split("..."))
    return any(re.fullmatch(pattern, got) for got in output)


def _run_session(steps: list[tuple[str, list[str]]], where: Path) -> list[str]:
    """Runs what it can of one block in ``where``; the tsa-bench commands it ran."""
    ran = []
    for cmd, shown in steps:
        words = shlex.split(cmd, comments=True)
        if words[0] == "printf":
            subprocess.run(["bash", "-c", cmd], cwd=where, check=True)
        elif words[0] == "cat" and "..." not in shown:
            (where / words[1]).write_text("".join(f"{line}\n" for line in shown), encoding="utf-8")
        elif words[0] == "tsa-bench" and "# header: " in cmd and not (where / words[2]).exists():
            header = cmd.split("# header: ", 1)[1].strip()
            n = len(header.split(","))
            rows = [",".join([f"{0.1 * k:g}"] + ["100"] * (n - 1)) for k in range(3)]
            (where / words[2]).write_text("\n".join([header, *rows]) + "\n", encoding="utf-8")
        if words[0] == "tsa-bench" and (where / words[2]).exists():
            done = CliRunner().invoke(main, words[1:], catch_exceptions=False, env={"COLUMNS": "200", "NO_COLOR": "1"})
            output = done.output.splitlines()
            missing = [line for line in shown if line.strip() != "..." and not _shown(line, output)]
            assert not missing, f"{cmd}\nshown on the page but not printed: {missing}\nprinted:\n{done.output}"
            failed = any(line.startswith("error:") for line in shown)
            assert (done.exit_code != 0) == failed, f"{cmd}: exit code {done.exit_code}\n{done.output}"
            ran.append(cmd)
    return ran


def test_importing_page_sessions_print_what_the_page_shows(tmp_path, monkeypatch):
    ran = []
    for i, steps in enumerate(_sessions("importing")):
        where = tmp_path / f"block{i}"
        where.mkdir()
        monkeypatch.chdir(where)
        ran += _run_session(steps, where)
    # the sessions whose input the page shows, each run
    made = {shlex.split(c)[2] for c in ran}
    assert {"nums.csv", "logger.tsv", "messung.csv", "r.csv", "caps.csv", "elapsed.csv"} <= made, ran
