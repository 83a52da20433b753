"""One run in memory: what a run file holds (docs/run-format.md), whoever read or built it.

Units: ``samples[name]`` in ``units[name]`` (the contract's units: s, turn, mm, ohm, V, N).

Contract: :class:`RunData` is plain data; reading and checking a file is
:func:`tsa_bench.store.reader.read_run`'s job, which fills it. ``segments`` and ``events``
are in the store's in-memory layouts (``SEGMENT_DTYPE``, ``EVENT_DTYPE``) or None.
Models, control and reports take a RunData and never read files themselves.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["RunData"]


@dataclass(frozen=True)
class RunData:
    """One run in memory. ``samples[name]`` are equal-length arrays in ``units[name]``.

    ``path``: the file it was read from (or a ``<...>`` name for a run built in memory).
    ``attrs``: the file's root attributes (``format``, ``exit_status``, ``reason``,
    ``backend``, ``created``, ...). ``samples``: every sample column, at least ``t`` (s,
    device time since the run started, strictly increasing), ``turns`` (turn), ``length``
    (mm), ``resistance`` (ohm, NaN while not measured), ``heater_voltage`` (V), ``load``
    (N), ``segment`` (plan index, -1 outside any) and ``motor_moving`` (0/1); extra columns
    (imported channels, tracking state) with their units in ``units``. ``segments`` and
    ``events``: the tables (module docstring) or None. ``protocol_text`` and ``bench_text``:
    the YAML as run ("" when the file has none). ``extra``: what the reader noted (e.g.
    ``truncated_rows`` of a run killed mid-write).
    """

    path: str
    attrs: dict[str, Any]
    samples: dict[str, np.ndarray]
    units: dict[str, str]
    segments: np.ndarray | None = None
    events: np.ndarray | None = None
    protocol_text: str = ""
    bench_text: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.samples["t"])

    @property
    def t_s(self) -> np.ndarray:
        """Sample times, s of device time since the run started."""
        return self.samples["t"]

    @property
    def exit_status(self) -> str:
        """"success", "aborted", "failed", or "running" for a run killed mid-write ("" if unset)."""
        return str(self.attrs.get("exit_status", ""))
