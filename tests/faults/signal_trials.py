"""Signal trials shared by the tests and scripts/signal_campaign.py.

* :func:`flush_trial`: a run in this process whose writer sends itself SIGINT or SIGTERM
  from inside a flush (between the column appends), optionally a second one while the
  file closes.
* :func:`cli_double_interrupt_trial`: `tsa-bench run` in its own process over a real
  serial link (a pseudo-terminal through the relay to the simulated bench); two
  signals at a random moment of the run, a few milliseconds apart.

Each returns a :class:`TrialResult`: the exit status (or exit code), whether the relay or
the device saw a STOP, and whether the file reads back (all columns the same length).
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from tests.faults.ptybench import ROOT, quick_bench, relayed_sim
from tests.faults.relay import FaultyPort, LinkFaults
from tests.runner.helpers import open_sim, plan_from_text, run_plan
from tsa_bench.protocol import msg
from tsa_bench.store import RunFileError, RunWriter, read_run


@dataclass
class TrialResult:
    outcome: str          # exit_status of the run, or "exit <code>" for the CLI
    stop_sent: bool
    readable: bool
    detail: str = ""


class SignallingWriter(RunWriter):
    """A RunWriter that sends itself ``signals`` while appending column ``column`` of
    flush number ``at_flush``, and ``at_close`` (if any) during the last flush."""

    def __init__(self, path, at_flush: int, column: int, signals: list[int], at_close: int | None = None) -> None:
        # a flush at every segment end; small chunks, so that flushes append sample rows (only whole
        # chunks are written during a run)
        super().__init__(path, min_flush_interval_s=0.0, chunk_rows=64)
        self.at_flush, self.column, self.signals, self.at_close = at_flush, column, signals, at_close
        self.sent_during_flush = False
        self.closing = False

    def on_start(self, start) -> None:
        super().on_start(start)
        for i, appender in enumerate(self._columns.values()):
            appender.append = self._hooked(appender.append, i)

    def _hooked(self, append, i):
        def hooked(data):
            if i == self.column and not self.sent_during_flush and self.flushes >= self.at_flush:
                self.sent_during_flush = True
                for sig in self.signals:
                    os.kill(os.getpid(), sig)
            if i == self.column and self.closing and self.at_close is not None:
                os.kill(os.getpid(), self.at_close)
                self.at_close = None
            return append(data)
        return hooked

    def on_stop(self, stop) -> None:
        self.closing = True
        super().on_stop(stop)


def _readable(path: Path) -> tuple[bool, str]:
    try:
        run = read_run(path)
    except RunFileError as exc:
        return False, str(exc)
    return True, run.exit_status


def flush_trial(tmp_path: Path, rng: random.Random, plan_text: str) -> TrialResult:
    sig = rng.choice([signal.SIGINT, signal.SIGTERM])
    signals = [sig] if rng.random() < 0.5 else [sig, rng.choice([signal.SIGINT, signal.SIGTERM])]
    at_close = rng.choice([None, signal.SIGINT, signal.SIGTERM])
    path = tmp_path / f"flush-{rng.getrandbits(32)}.h5"
    writer = SignallingWriter(path, at_flush=rng.randrange(1, 60), column=rng.randrange(13), signals=signals,
                              at_close=at_close)
    port = FaultyPort(open_sim(rng.randrange(1000)), LinkFaults())
    # documents at every read (not coalesced), so that there is a flush per segment end to hit
    stop, _, _ = run_plan(plan_from_text(plan_text), tmp_path, port=port, writer=writer, block_samples=1)
    ok, detail = _readable(path)
    device = port._port.device
    for _ in range(100):  # a STOP at speed decelerates at the device's limit (<= 50 ms): let it end
        if not device.active:
            break
        device.advance(0.01, 1 << 20)
    stop_sent = port.link.host_frames.count(msg.Stop) > 0 and not device.active
    return TrialResult(stop.exit_status, stop_sent, ok and detail == stop.exit_status,
                       f"flush {writer.at_flush} column {writer.column} signals {signals} close {at_close}: "
                       f"{stop.reason}; file {detail}")


def cli_double_interrupt_trial(tmp_path: Path, rng: random.Random) -> TrialResult:
    bench = quick_bench(tmp_path)
    out = tmp_path / f"cli-{rng.getrandbits(32)}.h5"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "host")}
    with relayed_sim(bench, speed=20, seed=rng.randrange(1000)) as relay:
        proc = subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", "run",
                                 str(ROOT / "configs/protocols/lifetime.yaml"), "--bench", str(bench),
                                 "--port", relay.path, "--output", str(out)],
                                cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            side = out.with_name(out.name + ".live")
            deadline = time.monotonic() + 60
            while not side.exists() and proc.poll() is None and time.monotonic() < deadline:
                time.sleep(0.01)
            time.sleep(rng.uniform(0.0, 0.6))
            proc.send_signal(signal.SIGINT)
            time.sleep(rng.uniform(0.0, 0.03))
            proc.send_signal(rng.choice([signal.SIGINT, signal.SIGTERM]))
            stdout, stderr = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        stop_sent = relay.link.host_frames.count(msg.Stop) > 0
    ok, detail = _readable(out)
    tail = (stderr.strip().splitlines() or [""])[-1]
    return TrialResult(f"exit {proc.returncode}", stop_sent, ok and detail == "aborted",
                       f"file {detail}; stderr: {tail}")
