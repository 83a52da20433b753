"""A catalogue row as a Python object, and whether its run file is still the one registered.

Units: ``load_g`` in g, ``device_time_s`` in s, sizes in bytes; datetimes naive UTC
(:meth:`RunRow.as_dict` gives ISO 8601 with ``Z``).

Contract of :meth:`RunRow.file_state`: "ok" when the file on this host has the size and
modification time registered (a cheap ``stat``; :meth:`RunRow.verify` also compares the
SHA-256); "missing" when it is gone; "changed" when it differs; "running" while the run
is still being recorded (no final hash yet); "elsewhere" when the row was registered on
another host. A row is never trusted past its file: callers show the state.
"""

from __future__ import annotations

import datetime as dt
import os
import socket
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any, Mapping

_HOST = socket.gethostname()


@dataclass(frozen=True)
class RunRow:
    """One run in the catalogue (fields as in :mod:`.schema`)."""

    id: int
    host: str
    path: str
    kind: str
    status: str
    reason: str = ""
    plan: str | None = None
    bench: str | None = None
    backend: str | None = None
    port: str | None = None
    rig: str | None = None
    sample: str | None = None
    load_g: float | None = None
    operator: str | None = None
    started: dt.datetime | None = None
    ended: dt.datetime | None = None
    device_time_s: float | None = None
    samples: int | None = None
    samples_lost: int | None = None
    segments_done: int | None = None
    n_segments: int | None = None
    sha256: str | None = None
    size_bytes: int | None = None
    mtime_ns: int | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    verdict: str | None = None
    verdict_detail: str | None = None
    diagnosed: dt.datetime | None = None
    resumed_from: str | None = None
    continued_in: str | None = None
    pid: int | None = None
    updated: dt.datetime | None = None

    @classmethod
    def from_mapping(cls, m: Mapping[str, Any]) -> "RunRow":
        names = {f.name for f in fields(cls)}
        values = {k: v for k, v in m.items() if k in names}
        values["meta"] = values.get("meta") or {}
        return cls(**values)

    @property
    def name(self) -> str:
        """The run file's name."""
        return Path(self.path).name

    @property
    def live_path(self) -> Path:
        """The live sidecar (``RUN.h5.live``) the recording process writes while it runs;
        :class:`tsa_bench.store.live.LiveTail` reads it."""
        return Path(self.path + ".live")

    def file_state(self) -> str:
        """"ok", "missing", "changed", "running" or "elsewhere" (module contract)."""
        if self.host != _HOST:
            return "elsewhere"
        try:
            st = os.stat(self.path)
        except FileNotFoundError:
            return "missing"
        except OSError:
            return "missing"
        if self.status == "running" and self.sha256 is None:
            return "running"
        if self.size_bytes is None or self.mtime_ns is None:
            return "changed"
        return "ok" if (st.st_size, st.st_mtime_ns) == (self.size_bytes, self.mtime_ns) else "changed"

    def verify(self) -> str:
        """:meth:`file_state`, and for an "ok" file its SHA-256 compared too."""
        state = self.file_state()
        if state != "ok" or self.sha256 is None:
            return state
        from tsa_bench.catalogue.runfiles import sha256_of

        return "ok" if sha256_of(self.path) == self.sha256 else "changed"

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: every field, datetimes as ISO 8601 UTC with ``Z``."""
        out = asdict(self)
        for key, value in out.items():
            if isinstance(value, dt.datetime):
                out[key] = value.isoformat(timespec="seconds") + "Z"
        return out
