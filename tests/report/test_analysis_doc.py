"""docs/analysis.md: its Python snippets and tsa-bench commands run against a simulated run."""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import shutil

import pytest
from click.testing import CliRunner

from tests.report.conftest import ROOT
from tsa_bench.cli import main

DOC = (ROOT / "docs" / "analysis.md").read_text()
BLOCKS = re.findall(r"^## (.+?)$|^```(\w+)\n(.*?)^```", DOC, flags=re.S | re.M)


def _blocks(lang: str) -> dict[str, str]:
    """{section title: code} of the fenced blocks in ``lang``."""
    out, section = {}, ""
    for title, block_lang, code in BLOCKS:
        if title:
            section = title.strip()
        elif block_lang == lang:
            out[section] = out.get(section, "") + code
    return out


@pytest.fixture
def in_run_dir(protocol_runs, tmp_path):
    shutil.copy(protocol_runs["twist-sweep-3ply"], tmp_path / "run.h5")
    old = os.getcwd()
    os.chdir(tmp_path)
    yield tmp_path
    os.chdir(old)


def _exec(code: str) -> str:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        exec(compile(code, "docs/analysis.md", "exec"), {})
    return buf.getvalue()


def test_the_doc_has_the_blocks_this_test_runs():
    py = _blocks("python")
    assert set(py) == {"h5py", "pandas"} and "h5read" in _blocks("matlab")["MATLAB"]
    assert len(_blocks("sh")) == 1


def test_h5py_snippet(in_run_dir):
    out = _exec(_blocks("python")["h5py"])
    assert re.match(r"success: 4933 samples, \d+ holds, R \d\.\d{3} ohm at rest", out), out


def test_pandas_snippet(in_run_dir):
    assert "resistance" in _exec(_blocks("python")["pandas"])


def test_commands(in_run_dir):
    commands = [line for line in next(iter(_blocks("sh").values())).splitlines() if line.strip()]
    for line in commands:
        args = shlex.split(line)
        assert args[0] == "tsa-bench"
        res = CliRunner().invoke(main, args[1:])
        assert res.exit_code == 0, (line, res.output)
    assert (in_run_dir / "run_report" / "index.html").exists()
    assert (in_run_dir / "csv" / "run.samples.csv").exists() and (in_run_dir / "reimported.h5").exists()
    assert "run ended: success" in res.output  # watch --once on the finished run
