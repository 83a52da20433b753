"""The catalogues the tests run against: SQLite in a temporary folder, and a real PostgreSQL.

PostgreSQL: ``$TSA_BENCH_TEST_POSTGRES`` (a URL of a database the test user may create
databases from), else the local socket's ``tsa_bench_test`` database that
scripts/setup-test-services.sh creates. Each test gets a database of its own, dropped
after it. Where no server answers, the PostgreSQL cases are skipped with the reason, and
fail on CI (tests/services.py).
"""

from __future__ import annotations

import os
import uuid

import pytest

from tests.services import unavailable

PG_BASE = os.environ.get("TSA_BENCH_TEST_POSTGRES", "postgresql:///tsa_bench_test?host=/var/run/postgresql")


def _admin_engine():
    from sqlalchemy import create_engine

    from tsa_bench.catalogue.database import _url_of

    return create_engine(_url_of(PG_BASE), isolation_level="AUTOCOMMIT")


@pytest.fixture
def pg_url():
    """A fresh PostgreSQL database's URL (skipped with the reason when no server answers)."""
    try:
        import psycopg  # noqa: F401
    except ImportError:
        unavailable("psycopg (the [postgres] extra, in [dev]) is not installed")
    from sqlalchemy import text
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import OperationalError

    admin = _admin_engine()
    name = f"tsa_test_{uuid.uuid4().hex[:12]}"
    try:
        with admin.connect() as conn:
            conn.execute(text(f'CREATE DATABASE "{name}"'))
    except OperationalError as exc:
        admin.dispose()
        unavailable(f"no PostgreSQL server at {PG_BASE} (scripts/setup-test-services.sh starts one): "
                    f"{str(exc.orig).strip().splitlines()[0]}")
    url = make_url(admin.url).set(database=name).render_as_string(hide_password=False)
    try:
        yield url
    finally:
        with admin.connect() as conn:
            conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()


@pytest.fixture(params=["sqlite", "postgresql"])
def catalogue_url(request, tmp_path):
    """Each test once on SQLite and once on PostgreSQL."""
    if request.param == "sqlite":
        return str(tmp_path / "catalogue.sqlite")
    return request.getfixturevalue("pg_url")
