"""docs/bluesky.md: its Python examples and tsa-bench commands run, in order, on the simulated bench."""

from __future__ import annotations

import glob
import re
import shlex

import bluesky.callbacks.best_effort as best_effort
import pytest
from click.testing import CliRunner

from tests.bluesky.helpers import ROOT
from tsa_bench.cli import main
from tsa_bench.store import read_run

DOC = (ROOT / "docs" / "bluesky.md").read_text()
BLOCKS = re.findall(r"^```(python|bash)\n(.*?)^```", DOC, flags=re.S | re.M)


class _TableOnly(best_effort.BestEffortCallback):
    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.disable_plots()


def test_the_examples_run_and_their_run_files_read_back(tmp_path, monkeypatch):
    # the live table stays; the live plot goes (drawn off-screen it costs about 1 s per event here)
    monkeypatch.setattr(best_effort, "BestEffortCallback", _TableOnly)
    monkeypatch.chdir(tmp_path)
    assert [lang for lang, _ in BLOCKS] == ["python", "bash", "python", "bash"]
    for lang, code in BLOCKS:
        if lang == "python":
            exec(compile(code, "docs/bluesky.md", "exec"), {"__name__": "docs_bluesky"})
            continue
        for line in code.strip().splitlines():
            args = [a for arg in shlex.split(line)[1:] for a in (sorted(glob.glob(arg)) or [arg])]
            res = CliRunner().invoke(main, args)
            assert res.exit_code == 0, f"{line}\n{res.output}"
    sweeps = [read_run(path) for path in glob.glob("runs/*.h5")]
    assert len(sweeps) == 3                                   # one run file per load
    for run in sweeps:
        assert run.attrs["exit_status"] == "success" and len(run.samples["turns"]) == 19
        assert max(run.samples["turns"]) == 81.0
    loads_g = sorted(run.samples["load"][0] / 9.80665e-3 for run in sweeps)    # N -> g
    assert loads_g == pytest.approx([150, 200, 250])
    (protocol,) = glob.glob("protocol-runs/*.h5")
    assert read_run(protocol).attrs["exit_status"] == "success"
    lines = (tmp_path / "sweep.jsonl").read_text().splitlines()
    assert lines[0].startswith('["start"') and lines[-1].startswith('["stop"')
