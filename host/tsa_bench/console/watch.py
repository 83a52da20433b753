"""`tsa-bench watch`: follow a run while it records, from its live sidecar.

Contract: :func:`watch` never opens a run file that is being written (see
:mod:`tsa_bench.store.live` for why); it tails ``RUN.h5.live`` and shows the latest t,
turns, length, resistance, heater voltage, load, segment, sample count, samples per
wall-clock second and sparklines of length and resistance, refreshed every
``interval_s``. It ends by itself and says so when the run ends (the end record; the
run file, then closed, gives the reason) or when the writer process is gone without
one (a killed run). Without a sidecar, a finished run file is summarised from the
file. Returns the exit code: 0 the run ended in success (or ``once``: state shown);
1 it ended aborted/failed or was killed; 2 nothing to watch.
"""

from __future__ import annotations

import collections
import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.live import Live
from rich.table import Table

from tsa_bench.console.output import make_console

from tsa_bench.store.live import LiveFormatError, LiveTail, sidecar_path

_BARS = "▁▂▃▄▅▆▇█"


def sparkline(values: list[float], width: int = 40) -> str:
    """Unicode bars of the last ``width`` finite values (blank where NaN)."""
    v = np.asarray(values[-width:], dtype=float)
    fin = v[np.isfinite(v)]
    if not len(fin):
        return ""
    lo, hi = float(fin.min()), float(fin.max())
    out = []
    for x in v:
        if not math.isfinite(x):
            out.append(" ")
        else:
            out.append(_BARS[0 if hi == lo else int((x - lo) / (hi - lo) * (len(_BARS) - 1))])
    return "".join(out)


class WatchState:
    """Latest values and rates from the records read so far (contract units)."""

    def __init__(self, n_segments: int = 0, history: int = 120) -> None:
        self.n_segments = n_segments
        self.samples = 0
        self.last: np.void | None = None
        self.resistance = float("nan")  # the latest sample's (NaN: not measured, e.g. while the heater is on)
        self.lengths: collections.deque = collections.deque(maxlen=history)
        self.resistances: collections.deque = collections.deque(maxlen=history)
        self._arrivals: collections.deque = collections.deque()  # (wall time, count)
        self.last_arrival = time.monotonic()

    def add(self, rec: np.ndarray, now: float | None = None) -> None:
        now = time.monotonic() if now is None else now
        if not len(rec):
            return
        self.samples += len(rec)
        self.last = rec[-1]
        self.resistance = float(rec["resistance"][-1])  # never a stale value from before heating
        step = max(1, len(rec) // 20)
        self.lengths.extend(rec["length"][::-1][::step][::-1].tolist())
        self.resistances.extend(rec["resistance"][::-1][::step][::-1].tolist())
        self._arrivals.append((now, len(rec)))
        self.last_arrival = now

    def rate(self, now: float | None = None, window_s: float = 3.0) -> float:
        """Samples per wall-clock second over the last ``window_s``."""
        now = time.monotonic() if now is None else now
        while self._arrivals and now - self._arrivals[0][0] > window_s:
            self._arrivals.popleft()
        n = sum(k for _, k in self._arrivals)
        return n / window_s if n else 0.0

    def resistance_text(self, unit: bool = True) -> str:
        """The latest resistance, or why there is none ("not measured (heater on)")."""
        if math.isfinite(self.resistance):
            return f"{self.resistance:.4f}" + (" ohm" if unit else "")
        heating = self.last is not None and float(self.last["heater_voltage"]) > 0
        return "not measured (heater on)" if heating else "not measured"

    def line(self) -> str:
        if self.last is None:
            return "waiting for the first sample ..."
        r = self.last
        seg = int(r["segment"])
        return (f"t={r['t']:.2f} s  turns={r['turns']:.3f} turn  length={r['length']:.2f} mm  "
                f"resistance={self.resistance_text()}  heater={r['heater_voltage']:.2f} V  load={r['load']:.3f} N  "
                f"segment {seg + 1}/{self.n_segments}  samples={self.samples}  rate={self.rate():.1f}/s")

    def table(self, title: str) -> Table:
        # units on a second header line and no borders: fits an 80-column terminal
        tab = Table(title=title, show_header=True, header_style="bold", box=None, padding=(0, 1))
        for col in ("t\ns", "turns\nturn", "length\nmm", "resistance\nohm", "heater\nV", "load\nN",
                    "segment", "samples", "rate\n1/s"):
            tab.add_column(col, justify="right", no_wrap=True)
        if self.last is not None:
            r = self.last
            tab.add_row(f"{r['t']:.2f}", f"{r['turns']:.3f}", f"{r['length']:.2f}",
                        self.resistance_text(unit=False),
                        f"{r['heater_voltage']:.2f}", f"{r['load']:.3f}", f"{int(r['segment']) + 1}/{self.n_segments}",
                        str(self.samples), f"{self.rate():.1f}")
        tab.caption = (f"length     {sparkline(list(self.lengths))}\n"
                       f"resistance {sparkline(list(self.resistances))}")
        return tab


def _summary_from_file(run_path: Path, echo: Callable[[str], None]) -> int:
    """A run without a sidecar: summarise it if it is closed; say so if it was killed."""
    from tsa_bench.store import RunFileError, read_run

    try:
        run = read_run(run_path)
    except RunFileError as exc:
        if "lock" in str(exc).lower():
            echo(f"error: {run_path} is being written by a process that publishes no live sidecar; "
                 "cannot read it safely until it ends")
        else:
            echo(f"error: {exc}")
        return 2
    n = len(run)
    last = f"; last sample t={run.samples['t'][-1]:.2f} s" if n else ""
    if run.exit_status == "running":
        echo(f"run was killed: {run_path} was never closed (exit_status 'running'); it holds {n} samples "
             f"up to its last flush{last}")
        return 1
    echo(f"run ended: {run.exit_status} ({run.attrs.get('reason', '')}); {n} samples{last}; file {run_path}")
    return 0 if run.exit_status == "success" else 1


def _closed_status(run_path: Path) -> tuple[str, str] | None:
    """(exit status, reason) of a run file its writer closed; None if it was not closed."""
    from tsa_bench.store import RunFileError, read_run

    try:
        run = read_run(run_path)
    except RunFileError:
        return None
    if run.exit_status == "running":
        return None
    return run.exit_status, str(run.attrs.get("reason", ""))


def _being_written(run_path: Path) -> bool:
    """The run file is open for writing by another process (HDF5's file lock says so), or
    is still the empty file a starting run reserved its name with: a run starting up,
    whose sidecar appears a moment after the run file."""
    from tsa_bench.store import RunFileError, read_run

    try:
        if run_path.stat().st_size == 0:
            return True
    except OSError:
        return False
    try:
        read_run(run_path)
    except RunFileError as exc:
        return "lock" in str(exc).lower()
    return False


def _open_tail(run_path: Path, wait_s: float) -> LiveTail | None:
    deadline = time.monotonic() + wait_s
    side = sidecar_path(run_path)
    while True:
        try:
            return LiveTail(side)
        except FileNotFoundError:
            if time.monotonic() >= deadline or (run_path.exists() and not _being_written(run_path)):
                return None
        time.sleep(0.1)


def watch(run_path: str | Path, *, plain: bool = False, once: bool = False, interval_s: float = 0.5,
          wait_s: float = 0.0, console: Console | None = None) -> int:
    """Follow ``run_path``; see the module contract."""
    run_path = Path(run_path)
    console = console or make_console()
    def echo(text: str) -> None:  # a message is one line however narrow the terminal: never hard-wrapped
        console.print(text, markup=False, highlight=False, soft_wrap=True)

    try:
        tail = _open_tail(run_path, wait_s)
    except LiveFormatError as exc:
        echo(f"error: {exc}")
        return 2
    except OSError as exc:
        echo(f"error: {sidecar_path(run_path)}: cannot read the live sidecar ({exc.strerror or exc})")
        return 2
    if tail is None:
        if not run_path.exists():
            echo(f"error: {run_path}: no such run file and no live sidecar {sidecar_path(run_path)}")
            return 2
        return _summary_from_file(run_path, echo)
    head = tail.header
    state = WatchState(head.get("n_segments", 0))
    title = f"{head.get('plan_name', '')}  ({run_path.name})"
    live = None
    try:
        if not plain and not once:
            live = Live(state.table(title), console=console, refresh_per_second=4)
            live.start()
        while True:
            state.add(tail.poll())
            if live is not None:
                live.update(state.table(title))
            elif not once or tail.ended:
                echo(state.line())
            if tail.ended:
                break
            if tail.writer_alive() is False:
                state.add(tail.poll())  # whatever it flushed before dying
                if tail.ended:
                    break
                if live is not None:
                    live.stop()
                    live = None
                closed = _closed_status(run_path)
                if closed is not None:   # the file was closed; the journal could not say so (a full disk)
                    status, reason = closed
                    echo(f"run ended: {status} ({reason}); {state.samples} samples seen; file {run_path}")
                    return 0 if status == "success" else 1
                echo(f"run was killed: writer process {head.get('pid')} is gone without ending the run; "
                     f"{state.samples} samples seen; tsa-bench run --resume {run_path} (or tsa-bench info) "
                     "recovers them from its journal")
                return 1
            if once:
                echo(state.line())
                echo(f"run in progress ({state.samples} samples so far)")
                return 0
            time.sleep(interval_s)
    except KeyboardInterrupt:
        if live is not None:
            live.stop()
        echo("stopped watching; the run goes on")
        return 0
    finally:
        if live is not None:
            live.stop()
        tail.close()
    status = tail.ended
    reason = ""
    try:  # the writer closed the run file before writing the end record
        from tsa_bench.store import read_run
        reason = str(read_run(run_path).attrs.get("reason", ""))
    except Exception:  # the run file is authoritative but optional here
        reason = "reason unavailable"
    echo(f"run ended: {status} ({reason}); {state.samples} samples; file {run_path}")
    return 0 if status == "success" else 1
