"""An error while the writer closes the run file is not swallowed: the file says "failed"
with the reason (never "running"), the run's journal is kept, `run` exits 1, and recovery
(`run --resume`) then puts the journal's samples into the file."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.store import read_run
from tsa_bench.store.live import LiveTail, sidecar_path
from tsa_bench.store.recover import recover_run

ROOT = Path(__file__).resolve().parents[2]
PROTOCOL = "name: p\ndefaults: {rate_turns_per_s: 2, accel_turns_per_s2: 20}\nsteps:\n  - move_to: {turns: 2}\n" \
           "  - hold: {duration_s: 3}\n"
#: `tsa-bench run` whose writer meets a bug while it closes the file.
BROKEN_CLOSE = (
    "import runpy, sys\n"
    "from tsa_bench.store import RunWriter\n"
    "real = RunWriter.flush\n"
    "def flush(self):\n"
    "    if self._closing:\n"
    "        raise RuntimeError('a bug while closing')\n"
    "    return real(self)\n"
    "RunWriter.flush = flush\n"
    "sys.argv = ['tsa-bench', 'run', *sys.argv[1:]]\n"
    "runpy.run_module('tsa_bench.cli', run_name='__main__')\n")


def test_an_error_while_closing_marks_the_file_failed_keeps_the_journal_and_exits_1(tmp_path):
    proto = tmp_path / "p.yaml"
    proto.write_text(PROTOCOL)
    out = tmp_path / "r.h5"
    res = subprocess.run([sys.executable, "-c", BROKEN_CLOSE, str(proto), "--output", str(out)], capture_output=True,
                         text=True, timeout=300, env={**os.environ, "PYTHONPATH": str(ROOT / "host")})
    assert res.returncode == 1, res.stdout + res.stderr
    assert "could not be closed properly: RuntimeError: a bug while closing" in res.stderr
    assert "Traceback" not in res.stderr
    run = read_run(out)
    assert run.exit_status == "failed" and "host error while closing the run file" in run.attrs["reason"]
    assert "the run itself ended success" in run.attrs["reason"]
    tail = LiveTail(sidecar_path(out))
    journal = tail.poll()
    assert len(journal) > len(run) and tail.ended == "success"   # the journal holds what the file lacks
    tail.close()
    res = CliRunner().invoke(main, ["info", str(out)])   # readable: shown as it is
    assert res.exit_code == 0 and "host error while closing" in res.output
    rec = recover_run(out)   # what `run --resume` does first: the file gets the journal's samples
    assert rec.path == out and rec.samples == len(journal) - len(run)
    assert len(read_run(out)) == len(journal) and not sidecar_path(out).exists()
