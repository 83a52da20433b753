"""A tsa-bench run file -> Bluesky documents (``tsa-bench export --documents RUN.h5``).

Units: each data key carries its column's units (the run file's: s, turn, mm, ohm, V, N).

Contract: :func:`run_documents` yields ``(name, document)`` pairs of one Bluesky run,
composed and checked against the event-model schemas by ``event_model.compose_run``:
a start (the run file's attributes, ``plan_name``, ``tsa_bench_run`` the file's path,
``time`` its ``created``), then the stream ``primary`` (every sample column, one event
per sample, sent as event pages of at most ``page_rows``; event times ``created + t``),
``segments`` (one event per row of /segments) and ``events`` (one per row of /events),
each descriptor carrying the protocol and bench texts as configuration, and a stop
(``exit_status`` "success", "abort" for "aborted", "fail" for "failed" and for a file
still "running": a killed run; ``reason`` the file's). Sources are
``tsa-bench:<file>#<quantity>``, so :class:`~tsa_bench.bluesky.bridge.RunFileWriter`
writes the documents back as an equivalent run file. :func:`write_jsonl` writes them as
JSON lines, one ``[name, document]`` array per line (NaN written as null: strict JSON).
Nothing here imports bluesky or ophyd-async: only event-model.
"""

from __future__ import annotations

import datetime as dt
import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np
from event_model import compose_run

from tsa_bench.bluesky.sources import source_of
from tsa_bench.store import read_run

PAGE_ROWS = 10_000
EXIT_STATUS = {"success": "success", "aborted": "abort", "failed": "fail"}
_SEGMENT_KEYS = (("index", "integer", "1"), ("kind", "string", ""), ("t_start", "number", "s"),
                 ("t_end", "number", "s"), ("completed", "integer", "1"), ("cycle", "integer", "1"),
                 ("source", "string", ""), ("params", "string", ""))
_EVENT_KEYS = (("t", "number", "s"), ("kind", "string", ""), ("detail", "string", ""))


def _plain(value: Any) -> Any:
    """A numpy scalar or bytes as a JSON-friendly Python value."""
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.generic):
        return value.item()
    return value


def _dtype(a: np.ndarray) -> str:
    return "integer" if a.dtype.kind in "iub" else "number" if a.dtype.kind == "f" else "string"


def _created(attrs: dict) -> float:
    try:
        return dt.datetime.fromisoformat(str(attrs.get("created", ""))).timestamp()
    except ValueError:
        return 0.0


def run_documents(path: str | Path, *, page_rows: int = PAGE_ROWS) -> Iterator[tuple[str, dict]]:
    """The Bluesky documents of one run file (see the module contract); RunFileError
    (from :func:`tsa_bench.store.read_run`) when the file cannot be read."""
    run = read_run(path)
    where = str(Path(path))
    t0 = _created(run.attrs)
    md = {k: _plain(v) for k, v in run.attrs.items() if k not in ("created",)}
    md.update(plan_name=str(run.attrs.get("plan_name", "tsa-bench run")), tsa_bench_run=where)
    bundle = compose_run(metadata=md, time=t0)
    yield "start", bundle.start_doc
    config_keys = {"protocol": run.protocol_text, "bench": run.bench_text}
    configuration = {"run_file": {
        "data": dict(config_keys),
        "timestamps": {k: t0 for k in config_keys},
        "data_keys": {k: {"dtype": "string", "shape": [], "source": source_of(where, k)} for k in config_keys}}}

    t = np.asarray(run.samples["t"], dtype=float)
    names = list(run.samples)
    data_keys = {n: {"dtype": _dtype(run.samples[n]), "shape": [], "source": source_of(where, n),
                     "units": run.units.get(n, "")} for n in names}
    primary = bundle.compose_descriptor(name="primary", data_keys=data_keys, configuration=configuration)
    yield "descriptor", primary.descriptor_doc
    for lo in range(0, len(t), page_rows):
        hi = min(lo + page_rows, len(t))
        times = (t0 + t[lo:hi]).tolist()
        data = {n: [_plain(v) for v in run.samples[n][lo:hi]] for n in names}
        yield "event_page", primary.compose_event_page(
            data=data, timestamps={n: times for n in names}, seq_num=list(range(lo + 1, hi + 1)), time=times,
            validate=False)
    for stream, table, keys, prefix in (("segments", run.segments, _SEGMENT_KEYS, "segment_"),
                                        ("events", run.events, _EVENT_KEYS, "event_")):
        if table is None or not len(table):
            continue
        dks = {f"{prefix}{k}": {"dtype": d, "shape": [], "source": source_of(where, f"{prefix}{k}"), "units": u}
               for k, d, u in keys}
        desc = bundle.compose_descriptor(name=stream, data_keys=dks, configuration=configuration)
        yield "descriptor", desc.descriptor_doc
        rows = [{k: _plain(row[k]) for k, _, _ in keys} for row in table]
        stamp_field = "t_end" if stream == "segments" else "t"
        times = [t0 + float(r[stamp_field]) for r in rows]
        data = {f"{prefix}{k}": [r[k] for r in rows] for k, _, _ in keys}
        yield "event_page", desc.compose_event_page(
            data=data, timestamps={k: times for k in data}, seq_num=list(range(1, len(rows) + 1)), time=times,
            validate=False)
    status = str(run.attrs.get("exit_status", ""))
    reason = str(run.attrs.get("reason", "")) or ("the run file was never closed: the run was killed"
                                                  if status == "running" else "")
    t_end = t0 + (float(t[-1]) if len(t) else 0.0)
    yield "stop", bundle.compose_stop(exit_status=EXIT_STATUS.get(status, "fail"), reason=reason, time=t_end)


def _strict(value: Any) -> Any:
    """NaN and infinities as None, through lists and dicts (strict JSON)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_strict(v) for v in value]
    return value


def write_jsonl(path: str | Path, out: IO[str], *, page_rows: int = PAGE_ROWS) -> int:
    """Write the run file's documents to ``out`` as JSON lines; the number of documents."""
    n = 0
    for name, doc in run_documents(path, page_rows=page_rows):
        out.write(json.dumps([name, _strict(dict(doc))], allow_nan=False, default=_plain) + "\n")
        n += 1
    return n
