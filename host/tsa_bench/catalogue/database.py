"""The catalogue database: open it, write rows that survive concurrent writers, search it.

Units and fields: :mod:`.schema`. Times are naive UTC.

Contract:

* :func:`open_catalogue` takes a SQLAlchemy URL (``sqlite:///runs/catalogue.sqlite``,
  ``postgresql://user@host/lab``; a bare ``postgresql://`` uses psycopg 3 when it is
  installed), a path to a SQLite file, or a folder (its :data:`CATALOGUE_FILE`). The
  table is created when missing; a catalogue of a newer schema is refused.
* SQLite: WAL journal, a busy timeout, and every write in ``BEGIN IMMEDIATE`` (the write
  lock taken first, so two writers wait in turn instead of failing on a lock upgrade).
  PostgreSQL: one transaction per write. Both: a write that meets a lock, a busy database
  or a dropped connection is retried with a growing pause until ``retry_s`` (default 60 s)
  has passed (opening: 3 s, so an absent server is said at once); only then does it
  raise :class:`CatalogueError`. A row is written whole or
  not at all.
* Readers never block writers (SQLite WAL; PostgreSQL MVCC).
"""

from __future__ import annotations

import datetime as dt
import os
import random
import socket
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, TypeVar

from sqlalchemy import Engine, create_engine, event, func, insert, select, update
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError, DBAPIError, IntegrityError, NoSuchModuleError, OperationalError, SQLAlchemyError

from tsa_bench.catalogue.rows import RunRow
from tsa_bench.catalogue.schema import SCHEMA_VERSION, info, metadata, runs
from tsa_bench.catalogue.where import Condition, WhereError, clauses, in_python, matches, parse_condition, parse_time

#: The SQLite catalogue's file name in a folder of runs.
CATALOGUE_FILE = "catalogue.sqlite"
#: Environment variable naming the catalogue every command uses unless told otherwise.
ENV_VAR = "TSA_BENCH_CATALOGUE"
BUSY_TIMEOUT_S = 30.0
RETRY_S = 60.0
#: Opening retries only this long (s): a server that is not there is said at once.
OPEN_RETRY_S = 3.0

T = TypeVar("T")


class CatalogueError(RuntimeError):
    """The catalogue cannot be opened, read or written; the message says which and why."""


def now_utc() -> dt.datetime:
    return dt.datetime.now(dt.timezone.utc).replace(tzinfo=None)


def _url_of(target: str | Path) -> str:
    text = str(target)
    if "://" in text:
        if text.startswith("postgresql://") or text.startswith("postgres://"):
            try:
                import psycopg  # noqa: F401
                return "postgresql+psycopg://" + text.split("://", 1)[1]
            except ImportError:
                return "postgresql://" + text.split("://", 1)[1]
        return text
    path = Path(text)
    if path.is_dir():
        path = path / CATALOGUE_FILE
    return f"sqlite:///{path.resolve()}"


def shown_url(url: str) -> str:
    """The URL without its password (for messages)."""
    try:
        return make_url(url).render_as_string(hide_password=True)
    except ArgumentError:
        return url


def _sqlite_engine(url: str) -> Engine:
    path = make_url(url).database
    if path and path != ":memory:":
        folder = Path(path).parent
        if not folder.is_dir():
            raise CatalogueError(f"{path}: its folder does not exist")
    engine = create_engine(url, connect_args={"timeout": BUSY_TIMEOUT_S, "check_same_thread": False})

    @event.listens_for(engine, "connect")
    def _connect(dbapi_conn, _record) -> None:
        dbapi_conn.isolation_level = None   # transactions begun below, not by the driver
        cur = dbapi_conn.cursor()
        if path and path != ":memory:":
            cur.execute("PRAGMA journal_mode=WAL")
        cur.execute(f"PRAGMA busy_timeout={int(BUSY_TIMEOUT_S * 1000)}")
        cur.execute("PRAGMA synchronous=NORMAL")
        cur.close()

    @event.listens_for(engine, "begin")
    def _begin(conn) -> None:
        conn.exec_driver_sql("BEGIN IMMEDIATE" if conn.get_execution_options().get("write") else "BEGIN")

    return engine


def _retryable(exc: DBAPIError) -> bool:
    if exc.connection_invalidated:
        return True
    text = str(exc.orig).lower() if exc.orig is not None else str(exc).lower()
    return any(word in text for word in ("locked", "busy", "deadlock", "could not serialize", "connection",
                                         "server closed", "terminating", "already exists", "duplicate key value "
                                         "violates unique constraint \"pg_"))


class Catalogue:
    """One catalogue database (module contract). Close it (or use ``with``) when done."""

    def __init__(self, url: str, *, retry_s: float = RETRY_S) -> None:
        self.url = url
        self.retry_s = retry_s
        self.host = socket.gethostname()
        try:
            self.engine = _sqlite_engine(url) if url.startswith("sqlite") else create_engine(
                url, pool_pre_ping=True, connect_args={"connect_timeout": 10})
        except NoSuchModuleError as exc:
            raise CatalogueError(f"catalogue {shown_url(url)}: no database driver for it ({exc}); for PostgreSQL "
                                 "install the extra: pip install 'tsa-bench[postgres]'") from None
        except ModuleNotFoundError as exc:
            raise CatalogueError(f"catalogue {shown_url(url)}: the database driver {exc.name} is not installed; "
                                 "for PostgreSQL: pip install 'tsa-bench[postgres]'") from None
        except ArgumentError as exc:
            raise CatalogueError(f"catalogue {url!r} is not a database URL: {exc}") from None
        self._write(self._create, retry_s=min(OPEN_RETRY_S, retry_s))

    # -- plumbing ------------------------------------------------------------
    def _write(self, work: Callable[[Any], T], retry_s: float | None = None) -> T:
        """``work(connection)`` in one write transaction, retried on locks and lost connections."""
        deadline = time.monotonic() + (self.retry_s if retry_s is None else retry_s)
        pause = 0.005
        while True:
            try:
                with self.engine.connect() as conn:
                    conn = conn.execution_options(write=True)
                    with conn.begin():
                        return work(conn)
            except DBAPIError as exc:
                if not _retryable(exc) or time.monotonic() >= deadline:
                    raise CatalogueError(f"catalogue {shown_url(self.url)}: {_first_line(exc)}") from None
            except SQLAlchemyError as exc:
                raise CatalogueError(f"catalogue {shown_url(self.url)}: {_first_line(exc)}") from None
            time.sleep(pause * (0.5 + random.random()))
            pause = min(pause * 2, 0.5)

    def _read(self, statement) -> list[Any]:
        deadline = time.monotonic() + self.retry_s
        while True:
            try:
                with self.engine.connect() as conn:
                    return list(conn.execute(statement))
            except DBAPIError as exc:
                if not _retryable(exc) or time.monotonic() >= deadline:
                    raise CatalogueError(f"catalogue {shown_url(self.url)}: {_first_line(exc)}") from None
                time.sleep(0.05)
            except SQLAlchemyError as exc:
                raise CatalogueError(f"catalogue {shown_url(self.url)}: {_first_line(exc)}") from None

    def _create(self, conn) -> None:
        metadata.create_all(conn, checkfirst=True)
        found = conn.execute(select(info.c.value).where(info.c.key == "schema_version")).scalar()
        if found is None:
            conn.execute(insert(info).values(key="schema_version", value=str(SCHEMA_VERSION)))
        elif int(found) > SCHEMA_VERSION:
            raise CatalogueError(f"catalogue {shown_url(self.url)} has schema version {found}; this tsa-bench "
                                 f"reads up to {SCHEMA_VERSION}: update tsa-bench")

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> "Catalogue":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- writing ------------------------------------------------------------
    def upsert(self, fields: dict[str, Any]) -> int:
        """Insert the row of ``fields["path"]`` on this host, or update the one there is (its
        ``id`` and any verdict stay); returns the id. ``fields`` are :mod:`.schema` columns."""
        values = {k: v for k, v in fields.items() if k in runs.c and k != "id"}
        values.setdefault("host", self.host)
        values["updated"] = now_utc()
        values.setdefault("status", "running")
        values.setdefault("kind", "recorded")
        values.setdefault("reason", "")

        def work(conn) -> int:
            key = (runs.c.host == values["host"]) & (runs.c.path == values["path"])
            found = conn.execute(select(runs.c.id).where(key)).scalar()
            if found is not None:
                conn.execute(update(runs).where(runs.c.id == found).values(**values))
                return int(found)
            try:
                with conn.begin_nested():
                    return int(conn.execute(insert(runs).values(**values).returning(runs.c.id)).scalar_one())
            except IntegrityError:   # another writer inserted the same file meanwhile
                found = conn.execute(select(runs.c.id).where(key)).scalar_one()
                conn.execute(update(runs).where(runs.c.id == found).values(**values))
                return int(found)

        return self._write(work)

    def update(self, run_id: int, fields: dict[str, Any]) -> None:
        """Change some fields of row ``run_id``."""
        values = {k: v for k, v in fields.items() if k in runs.c and k not in ("id", "host", "path")}
        values["updated"] = now_utc()
        self._write(lambda conn: conn.execute(update(runs).where(runs.c.id == run_id).values(**values)))

    def set_verdict(self, path: str | Path, verdict: str, detail: str = "") -> int | None:
        """Record a ``diagnose`` verdict on the row of ``path`` (this host); the row's id, None if absent."""
        key = (runs.c.host == self.host) & (runs.c.path == str(Path(path).resolve()))

        def work(conn) -> int | None:
            found = conn.execute(select(runs.c.id).where(key)).scalar()
            if found is not None:
                conn.execute(update(runs).where(runs.c.id == found).values(
                    verdict=verdict, verdict_detail=detail, diagnosed=now_utc(), updated=now_utc()))
            return found

        return self._write(work)

    def forget(self, run_id: int) -> None:
        """Delete row ``run_id`` (the run file is not touched)."""
        self._write(lambda conn: conn.execute(runs.delete().where(runs.c.id == run_id)))

    # -- reading -------------------------------------------------------------
    def search(self, where: Iterable[str | Condition] = (), *, status: str | Iterable[str] | None = None,
               since: str | dt.datetime | None = None, until: str | dt.datetime | None = None,
               folder: str | Path | None = None, limit: int | None = None, newest_first: bool = True) -> list[RunRow]:
        """Rows matching every condition (``"sample=S3"``, ``"load_g>=200"``: :mod:`.where`),
        with one of the statuses, started at or after ``since`` and before ``until`` (a date
        or ISO time; local time unless it has a zone), whose file is directly in ``folder``
        on this host; newest first unless told; at most ``limit``. WhereError on a bad condition."""
        conditions = [c if isinstance(c, Condition) else parse_condition(c) for c in where]
        query = select(runs)
        cond = clauses(conditions)
        if cond is not None:
            query = query.where(cond)
        if status is not None:
            statuses = [status] if isinstance(status, str) else list(status)
            query = query.where(runs.c.status.in_(statuses))
        for bound, op in ((since, ">="), (until, "<")):
            if bound is not None:
                when = bound if isinstance(bound, dt.datetime) else _time(bound, op)
                query = query.where(runs.c.started >= when if op == ">=" else runs.c.started < when)
        if folder is not None:
            prefix = str(Path(folder).resolve()).rstrip("/") + "/"
            query = query.where(runs.c.host == self.host).where(
                func.substr(runs.c.path, 1, len(prefix)) == prefix)
        order = runs.c.started.desc() if newest_first else runs.c.started.asc()
        query = query.order_by(order, runs.c.id.desc() if newest_first else runs.c.id.asc())
        later = [c for c in conditions if in_python(c)]
        if limit is not None and not later and folder is None:
            query = query.limit(int(limit))
        rows = [RunRow.from_mapping(r._mapping) for r in self._read(query)]
        if folder is not None:   # directly in the folder, not below it
            rows = [r for r in rows if "/" not in r.path[len(prefix):]]
        rows = [r for r in rows if all(matches(c, r.meta) for c in later)]
        return rows if limit is None else rows[:int(limit)]

    def get(self, run_id: int) -> RunRow | None:
        """The row ``run_id``, or None."""
        found = self._read(select(runs).where(runs.c.id == int(run_id)))
        return RunRow.from_mapping(found[0]._mapping) if found else None

    def by_path(self, path: str | Path, host: str | None = None) -> RunRow | None:
        """The row of the run file ``path`` (on ``host``, default this one), or None."""
        found = self._read(select(runs).where(runs.c.host == (host or self.host))
                           .where(runs.c.path == str(Path(path).resolve())))
        return RunRow.from_mapping(found[0]._mapping) if found else None

    def count(self) -> int:
        return int(self._read(select(func.count()).select_from(runs))[0][0])


def _time(text: str, op: str) -> dt.datetime:
    try:
        return parse_time(text)
    except ValueError:
        which = "--since" if op == ">=" else "--until"
        raise WhereError(f"{which} {text!r}: not a date (2026-11-01) or an ISO time (2026-11-01T14:30)") from None


def _first_line(exc: Exception) -> str:
    text = str(getattr(exc, "orig", None) or exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def open_catalogue(target: str | Path, *, retry_s: float = RETRY_S) -> Catalogue:
    """The catalogue at ``target`` (module contract); CatalogueError if it cannot be opened."""
    return Catalogue(_url_of(target), retry_s=retry_s)


def default_target(folder: str | Path) -> str:
    """The catalogue a command uses for runs in ``folder``: $TSA_BENCH_CATALOGUE, else the
    SQLite file :data:`CATALOGUE_FILE` in that folder."""
    return os.environ.get(ENV_VAR) or str(Path(folder) / CATALOGUE_FILE)
