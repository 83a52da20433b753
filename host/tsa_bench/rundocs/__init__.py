"""What the runner emits, and the interface its consumers implement.

Bluesky-style: the runner executes a plan and emits documents; storage, progress
display and logs subscribe. Contract of :class:`RunConsumer`: ``on_start`` exactly
once first, then any interleaving of ``on_samples``, ``on_segment`` and ``on_event``
in device-time order per kind, then ``on_stop`` exactly once (also after an abort or
a failure, so a consumer can close cleanly). Times are seconds of device time since
the run started. Consumers must not raise; a consumer that does ends the run as
failed. A consumer that runs out of room raises :class:`StorageFull` (message
"disk full: ..."), which ends the run as failed with that reason, and must still
close cleanly in ``on_stop``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

#: Sample columns in physical units, with their units; raw columns follow.
SAMPLE_COLUMNS: dict[str, tuple[str, str]] = {
    # name: (numpy dtype, units)
    "t": ("f8", "s"),
    "turns": ("f8", "turn"),
    "length": ("f8", "mm"),
    "resistance": ("f8", "ohm"),
    "heater_voltage": ("f8", "V"),
    "load": ("f8", "N"),
    "segment": ("i4", "1"),
    "motor_moving": ("u1", "1"),
    "counter": ("u4", "1"),
    "step_position": ("i4", "step"),
    "position_raw": ("i2", "count"),
    "resistance_raw": ("i4", "count"),
    "adc_flags": ("u1", "1"),
}


class StorageFull(OSError):
    """A consumer has no room left to store the run; the message starts with "disk full"."""


@dataclass
class SampleBlock:
    """A batch of consecutive samples as equal-length columns (keys of SAMPLE_COLUMNS and of
    the run's ``RunStart.extra_columns``)."""

    columns: dict[str, np.ndarray]

    def __len__(self) -> int:
        return len(self.columns["t"])


@dataclass(frozen=True)
class RunStart:
    """Everything known before the first command moves anything."""

    plan_name: str
    protocol_text: str
    protocol_path: str | None
    bench_text: str
    bench_path: str | None
    backend: str                 # "serial" | "sim" | "simavr"
    port: str
    firmware: str                # "major.minor.patch"
    identity: dict[str, Any]
    n_segments: int
    estimated_duration_s: float
    metadata: dict[str, Any] = field(default_factory=dict)
    extra_attrs: dict[str, Any] = field(default_factory=dict)   # more root attributes (a resumed run's link)
    # more sample columns every block carries: name -> (numpy dtype, units, {attribute: text})
    extra_columns: dict[str, tuple[str, str, dict[str, str]]] = field(default_factory=dict)


@dataclass(frozen=True)
class SegmentRecord:
    """One executed plan step (emitted when it ends, or when the run stops during it)."""

    index: int
    kind: str
    t_start: float
    t_end: float
    params: dict[str, Any]
    source: str
    cycle: int | None
    completed: bool


@dataclass(frozen=True)
class EventRecord:
    """Something that happened: device events, prompts, sample gaps, retransmissions."""

    t: float
    kind: str
    detail: str


@dataclass(frozen=True)
class RunStop:
    """How the run ended. ``exit_status`` is "success", "aborted" or "failed", ``reason`` says
    why (empty on success); ``t_end`` s of device time; ``samples`` stored, ``samples_lost``
    (counter gaps), ``segments_done``; ``wall_time_s`` s the run took."""

    exit_status: str
    reason: str
    t_end: float
    samples: int
    samples_lost: int
    segments_done: int
    wall_time_s: float
    attrs: dict[str, Any] = field(default_factory=dict)   # more root attributes (the clock fits)


class RunConsumer(Protocol):
    def on_start(self, start: RunStart) -> None: ...
    def on_samples(self, block: SampleBlock) -> None: ...
    def on_segment(self, segment: SegmentRecord) -> None: ...
    def on_event(self, event: EventRecord) -> None: ...
    def on_stop(self, stop: RunStop) -> None: ...
