"""Live progress display, a run consumer.

Contract: shows segment i of N, cycle, device time, ETA and the latest length and
resistance while a run executes, refreshed by rich at a few Hz in its own thread,
so the runner only stores numbers here (cheap at any sample rate). Disabled when the
console is not a terminal (CI logs stay readable). :meth:`ProgressDisplay.pause` and
:meth:`~ProgressDisplay.resume` let an operator channel take the terminal while a
person is asked (:class:`tsa_bench.operator.Pausable`).
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

from tsa_bench.rundocs import EventRecord, RunStart, RunStop, SampleBlock, SegmentRecord

if TYPE_CHECKING:  # rich is imported where a display is made (hms alone needs none)
    from rich.console import Console
    from rich.live import Live
    from rich.text import Text


def hms(seconds: float) -> str:
    if not math.isfinite(seconds) or seconds < 0:
        return "--:--:--"
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


class ProgressDisplay:
    """Rich live line; see the module contract."""

    def __init__(self, console: Console | None = None) -> None:
        from tsa_bench.console.output import make_console

        # no markup or highlighting: text printed while the line shows (a redirected print, a
        # prompt) comes out exactly as written, brackets and parentheses included
        self.console = console or make_console(stderr=True, markup=False)
        self.enabled = self.console.is_terminal
        self._live: Live | None = None
        self.n_segments = 0
        self.done = 0
        self.current = ""
        self.cycle: int | None = None
        self.t = 0.0
        self.estimate = float("nan")
        self.length = float("nan")
        self.resistance = float("nan")   # the latest sample's: NaN = not measured
        self.heater_V = 0.0
        self.samples = 0
        self.notes = 0
        self._wall0 = time.monotonic()

    def __rich__(self) -> Text:
        from rich.text import Text

        frac = self.done / self.n_segments if self.n_segments else 0.0
        bar_len = 24
        filled = int(frac * bar_len)
        wall = time.monotonic() - self._wall0
        speed = self.t / wall if wall > 0 and self.t > 0 else float("nan")
        eta = (self.estimate - self.t) / speed if speed == speed and speed > 0 else float("nan")
        cycle = f" cycle {self.cycle}" if self.cycle is not None else ""
        text = Text()
        text.append("█" * filled + "░" * (bar_len - filled), style="cyan")
        text.append(f" segment {self.done}/{self.n_segments}{cycle} {self.current}  ")
        text.append(f"device {hms(self.t)} / ~{hms(self.estimate)}  ETA {hms(eta)}  ")
        text.append(f"L {self.length:7.2f} mm  R {self.resistance_text()}  ", style="bold")
        text.append(f"{self.samples} samples")
        return text

    def on_start(self, start: RunStart) -> None:
        self.n_segments = start.n_segments
        self.estimate = start.estimated_duration_s
        self._wall0 = time.monotonic()
        if self.enabled:
            from rich.live import Live

            self._live = Live(self, console=self.console, refresh_per_second=4, transient=True)
            self._live.start()

    def on_samples(self, block: SampleBlock) -> None:
        c = block.columns
        self.samples += len(block)
        self.t = float(c["t"][-1])
        self.length = float(c["length"][-1])
        self.resistance = float(c["resistance"][-1])  # never a stale value from before heating
        self.heater_V = float(c["heater_voltage"][-1])

    def resistance_text(self) -> str:
        """The latest resistance, or why there is none."""
        if math.isfinite(self.resistance):
            return f"{self.resistance:8.4f} ohm"
        return "not measured (heater on)" if self.heater_V > 0 else "not measured"

    def on_segment(self, s: SegmentRecord) -> None:
        self.done = s.index + 1
        self.current = s.kind
        self.cycle = s.cycle
        self.t = max(self.t, s.t_end)

    def on_event(self, e: EventRecord) -> None:
        if e.kind in ("prompt", "sample_gap", "fault", "queue_underrun", "stop_sent"):
            self.notes += 1
            if self._live is not None:
                from rich.text import Text

                # a Text, not markup: a prompt or a reason may hold "[" and "]"
                self._live.console.print(Text(f"{hms(e.t)} {e.kind}: {e.detail}", style="yellow"))

    def pause(self) -> None:
        """Take the line off the screen (a person is being asked); :meth:`resume` brings it back."""
        if self._live is not None and self._live.is_started:
            self._live.stop()

    def resume(self) -> None:
        if self._live is not None and not self._live.is_started:
            self._live.start()

    def on_stop(self, stop: RunStop) -> None:
        if self._live is not None:
            self._live.stop()
            self._live = None
