"""The catalogue's one table: a row per run file, and what each searchable field is.

Units: ``load_g`` in g, ``device_time_s`` in s of device time, sizes in bytes, times in UTC
(naive ``datetime`` values hold UTC). A row is keyed by (``host``, ``path``): the same
file registered twice (a rebuild after a run registered itself) updates one row and keeps
its ``id``.
"""

from __future__ import annotations

from sqlalchemy import (
    JSON, BigInteger, Column, DateTime, Float, Index, Integer, MetaData, String, Table, Text, UniqueConstraint,
)

#: The catalogue's schema version (``catalogue_info``); a newer one is refused.
SCHEMA_VERSION = 1

metadata = MetaData()

runs = Table(
    "runs", metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("host", String(255), nullable=False),        # the host whose disk holds the file
    Column("path", Text, nullable=False),               # absolute path of the run file on that host
    Column("kind", String(16), nullable=False),         # recorded | resumed | imported
    Column("status", String(16), nullable=False),       # running | success | aborted | failed | killed
    Column("reason", Text, nullable=False, default=""),
    Column("plan", String(255)),
    Column("bench", String(255)),
    Column("backend", String(16)),                      # sim | simavr | serial | import
    Column("port", Text),
    Column("rig", String(255)),
    Column("sample", String(255)),
    Column("load_g", Float),
    Column("operator", String(255)),
    Column("started", DateTime),
    Column("ended", DateTime),
    Column("device_time_s", Float),
    Column("samples", BigInteger),
    Column("samples_lost", BigInteger),
    Column("segments_done", Integer),
    Column("n_segments", Integer),
    Column("sha256", String(64)),                       # of the closed file; None while running
    Column("size_bytes", BigInteger),
    Column("mtime_ns", BigInteger),
    Column("meta", JSON),                               # the run's metadata (protocol metadata and --meta)
    Column("verdict", String(32)),                      # of the last `diagnose` of this run
    Column("verdict_detail", Text),
    Column("diagnosed", DateTime),
    Column("resumed_from", Text),
    Column("continued_in", Text),
    Column("pid", Integer),                             # of the recording process, while running
    Column("updated", DateTime, nullable=False),
    UniqueConstraint("host", "path", name="runs_host_path"),
)
for _name in ("status", "started", "sample", "load_g", "rig", "plan", "operator"):
    Index(f"runs_{_name}", runs.c[_name])

info = Table(
    "catalogue_info", metadata,
    Column("key", String(64), primary_key=True),
    Column("value", Text, nullable=False),
)

#: Searchable fields and their kind: "text", "number" or "time" (``--where`` and ``search``).
FIELDS: dict[str, str] = {
    "id": "number", "host": "text", "path": "text", "kind": "text", "status": "text", "reason": "text",
    "plan": "text", "bench": "text", "backend": "text", "port": "text", "rig": "text", "sample": "text",
    "load_g": "number", "operator": "text", "started": "time", "ended": "time", "device_time_s": "number",
    "samples": "number", "samples_lost": "number", "segments_done": "number", "n_segments": "number",
    "sha256": "text", "size_bytes": "number", "verdict": "text", "diagnosed": "time",
    "resumed_from": "text", "continued_in": "text",
}

#: Metadata keys that are also columns of their own (copied from the run's metadata).
PROMOTED_META = ("rig", "sample", "operator", "load_g")
