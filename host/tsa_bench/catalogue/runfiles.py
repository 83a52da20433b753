"""What a run file says about itself, for a catalogue row; read safely from untrusted files.

Units: ``load_g`` in g, ``device_time_s`` in s, sizes in bytes; times naive UTC.

Contract: :func:`file_facts` reads a run file's root attributes, the length of its
samples and the ``completed`` column of its segments (never the samples themselves) and
returns the row fields (:mod:`.schema`) a run file determines, with its size, mtime and
SHA-256. A run file still marked "running" is "running" while its live sidecar's writer
lives on this host, else "killed". The load is the metadata's ``load_g`` when given, else
the protocol's top-level ``load_g`` (a ``$name`` there resolved from the run's
``protocol_variables`` metadata, then the protocol's ``variables``).

:class:`BoundedReader` reads files this process did not write: in one forked child kept
for many files (a damaged file can make the HDF5 library loop or allocate without bound,
as :mod:`tsa_bench.store.probe` explains), each file within ``timeout_s``; a child that
hangs or crashes is replaced, and that file gets a one-line problem instead of facts.
"""

from __future__ import annotations

import datetime as dt
import functools
import hashlib
import json
import os
import signal
import threading
from collections import deque
from collections.abc import Iterable, Iterator
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

from tsa_bench.store.hdf5 import FORMAT as RUN_FORMAT
from tsa_bench.store.probe import MEMORY_LIMIT_BYTES, TIMEOUT_S, limit_cpu, limit_memory


def _text(value: Any) -> str:
    if isinstance(value, bytes):
        return value.decode(errors="replace")
    if hasattr(value, "item"):
        return str(value.item())
    return str(value)


def sha256_of(path: str | Path) -> str:
    """Hex SHA-256 of the file's bytes."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def utc(iso: str) -> dt.datetime | None:
    """An ISO time with a zone (a run file's ``created``) as naive UTC; None if unreadable."""
    try:
        value = dt.datetime.fromisoformat(iso)
    except (TypeError, ValueError):
        return None
    if value.tzinfo is None:
        value = value.astimezone()
    return value.astimezone(dt.timezone.utc).replace(tzinfo=None)


@functools.lru_cache(maxsize=64)
def _yaml(text: str) -> Any:
    """Plain data of a YAML text stored in a run file (libyaml's safe loader when there is
    one; remembered, as a lab's runs share their bench and protocol texts: a rebuild reads
    a thousand); None when it does not parse. Callers only read the result. Files written
    by someone else are read in :class:`BoundedReader`'s child, under its memory and time limits."""
    import yaml

    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        return yaml.load(text, Loader=loader) if text else None
    except yaml.YAMLError:
        return None


def protocol_load_g(protocol_text: str, variables: dict[str, Any] | None = None) -> float | None:
    """The protocol's top-level ``load_g`` (g), a ``$name`` resolved; None when it declares none."""
    doc = _yaml(protocol_text)
    if not isinstance(doc, dict):
        return None
    value = doc.get("load_g")
    if isinstance(value, str) and value.startswith("$"):
        name = value.strip("${}")
        declared = doc.get("variables") if isinstance(doc.get("variables"), dict) else {}
        value = (variables or {}).get(name, declared.get(name))
    try:
        return float(value) if value is not None and not isinstance(value, bool) else None
    except (TypeError, ValueError):
        return None


def bench_name(bench_text: str) -> str | None:
    """The ``name`` of a bench file's text."""
    doc = _yaml(bench_text)
    return str(doc["name"]) if isinstance(doc, dict) and "name" in doc else None


def meta_fields(meta: dict[str, Any], plan_load_g: float | None) -> dict[str, Any]:
    """The promoted columns (rig, sample, operator, load_g) from a run's metadata."""
    out: dict[str, Any] = {k: (str(meta[k]) if meta.get(k) is not None else None) for k in ("rig", "sample", "operator")}
    load = meta.get("load_g", plan_load_g)
    try:
        out["load_g"] = float(load) if load is not None and load != "" else None
    except (TypeError, ValueError):
        out["load_g"] = None
    return out


def file_facts(path: str | Path, *, with_hash: bool = True) -> dict[str, Any]:
    """The row fields ``path`` determines (module contract); ValueError when it is not a run file."""
    import h5py
    import numpy as np

    from tsa_bench.store.live import recording

    p = Path(path).resolve()
    st = p.stat()
    with h5py.File(p, "r") as f:
        a = f.attrs
        if _text(a.get("format", "")) != RUN_FORMAT:
            raise ValueError("not a tsa-bench run file")
        try:
            meta = json.loads(_text(a.get("metadata", "{}")))
        except json.JSONDecodeError:
            meta = {}
        meta = meta if isinstance(meta, dict) else {}
        samples = int(f["samples/t"].shape[0]) if "samples/t" in f else 0
        done = None
        segs = f.get("segments")
        if segs is not None and segs.dtype.names and "completed" in segs.dtype.names:
            done = int(np.count_nonzero(segs["completed"][()]))
        protocol = _text(f["config/protocol"][()]) if "config/protocol" in f else ""
        bench = _text(f["config/bench"][()]) if "config/bench" in f else ""
        status = _text(a.get("exit_status", "?"))
        started = utc(_text(a.get("created", "")))
        wall = float(a["wall_time_s"]) if "wall_time_s" in a else None
        backend = _text(a.get("backend", ""))
        facts: dict[str, Any] = dict(
            path=str(p), status=status, reason=_text(a.get("reason", "")),
            kind="imported" if backend == "import" else ("resumed" if "resumed_from" in a else "recorded"),
            plan=_text(a.get("plan_name", "")) or None, bench=bench_name(bench), backend=backend or None,
            port=_text(a.get("port", "")) or None, started=started,
            ended=(started + dt.timedelta(seconds=wall)) if started is not None and wall is not None else None,
            device_time_s=float(a["duration_s"]) if "duration_s" in a else (
                float(f["samples/t"][-1]) if samples else None),
            samples=samples, samples_lost=int(a["samples_lost"]) if "samples_lost" in a else None,
            segments_done=done, n_segments=int(a["n_segments"]) if "n_segments" in a else None,
            meta=meta, resumed_from=_text(a["resumed_from"]) if "resumed_from" in a else None,
            continued_in=_text(a["continued_in"]) if "continued_in" in a else None)
    if status == "running":
        facts["status"] = "running" if recording(p) else "killed"
    variables = meta.get("protocol_variables") if isinstance(meta.get("protocol_variables"), dict) else None
    facts.update(meta_fields(meta, protocol_load_g(protocol, variables)))
    facts.update(size_bytes=st.st_size, mtime_ns=st.st_mtime_ns,
                 sha256=sha256_of(p) if with_hash and facts["status"] != "running" else None)
    return facts


def _child_loop(conn: Connection, with_hash: bool) -> None:  # pragma: no cover - runs in the child
    limit_memory()
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # the parent decides what Ctrl-C does
    while True:
        try:
            path = conn.recv()
        except EOFError:
            break
        if path is None:
            break
        limit_cpu()   # each file its own CPU budget: the child lives for many files
        try:
            conn.send((file_facts(path, with_hash=with_hash), None))
        except MemoryError:
            conn.send((None, f"damaged HDF5 file: reading it needed more than {MEMORY_LIMIT_BYTES >> 30} GiB"))
        except Exception as exc:  # h5py reports damaged files with many exception types
            conn.send((None, str(exc) if isinstance(exc, ValueError) else
                       f"not a readable HDF5 run file ({type(exc).__name__}: {exc})"))
    os._exit(0)


class _Child:
    """One forked reader and the paths sent to it, in order."""

    def __init__(self, with_hash: bool, timeout_s: float) -> None:
        self.with_hash, self.timeout_s = with_hash, timeout_s
        self.proc = None
        self.conn: Connection | None = None
        self.sent: deque[Path] = deque()

    def start(self) -> None:
        import multiprocessing

        # fork is quick; with other threads running one may hold h5py's lock at the fork, so
        # then a fresh interpreter (as tsa_bench.store.probe does)
        fork = hasattr(os, "fork") and threading.active_count() == 1
        ctx = multiprocessing.get_context("fork" if fork else "spawn")
        parent, child = ctx.Pipe()
        self.proc = ctx.Process(target=_child_loop, args=(child, self.with_hash), daemon=True)
        self.proc.start()
        child.close()
        self.conn = parent

    def stop(self, kill: bool) -> None:
        if self.proc is None:
            return
        try:
            if kill:
                self.proc.kill()
            else:
                self.conn.send(None)  # type: ignore[union-attr]
        except (OSError, ValueError):
            pass
        self.proc.join(10)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join()
        self.conn.close()  # type: ignore[union-attr]
        self.proc, self.conn = None, None

    def send(self, path: Path, again: bool = False) -> None:
        if self.proc is None:
            self.start()
        assert self.conn is not None
        self.conn.send(str(path))
        if not again:
            self.sent.append(path)

    def receive(self) -> tuple[Path, dict[str, Any] | None, str | None]:
        """The oldest path sent and what the child found; a lost child is replaced and
        the paths still waiting are sent to the new one."""
        assert self.conn is not None and self.proc is not None
        path = self.sent.popleft()
        try:
            if self.conn.poll(self.timeout_s):
                facts, why = self.conn.recv()
                return path, facts, why
            self.stop(kill=True)
            why = (f"damaged HDF5 file: reading its metadata did not finish in {self.timeout_s:g} s "
                   "(the HDF5 library loops on it)")
        except (EOFError, OSError):
            code = self.proc.exitcode
            self.stop(kill=True)
            why = f"damaged HDF5 file: the HDF5 library crashed reading it (exit {code})"
        for waiting in self.sent:
            self.send(waiting, again=True)
        return path, None, why


class BoundedReader:
    """Facts of untrusted files, read in forked children (module contract). Use as a context manager."""

    def __init__(self, *, with_hash: bool = True, timeout_s: float = TIMEOUT_S, workers: int = 2) -> None:
        self._children = [_Child(with_hash, timeout_s) for _ in range(max(1, workers))]

    def read(self, path: str | Path) -> tuple[dict[str, Any] | None, str | None]:
        """(facts, None) or (None, why this file gives none)."""
        (_, facts, why), = self.read_all([path])
        return facts, why

    def read_all(self, paths: Iterable[str | Path]) -> Iterator[tuple[Path, dict[str, Any] | None, str | None]]:
        """(path, facts, why) for each path, in order. File k goes to child k mod workers,
        which reads ahead while the caller handles earlier files."""
        todo = [Path(p) for p in paths]
        n = len(self._children)
        ahead = 2 * n
        for k in range(min(ahead, len(todo))):
            self._children[k % n].send(todo[k])
        for k in range(len(todo)):
            yield self._children[k % n].receive()
            if k + ahead < len(todo):
                self._children[(k + ahead) % n].send(todo[k + ahead])

    def __enter__(self) -> "BoundedReader":
        return self

    def __exit__(self, *exc: object) -> None:
        for child in self._children:
            child.stop(kill=False)
