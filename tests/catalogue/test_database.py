"""The catalogue database on SQLite and on a real PostgreSQL: rows, search, concurrent writers."""

from __future__ import annotations

import datetime as dt
import json
import multiprocessing

import pytest

from tsa_bench import catalogue
from tsa_bench.catalogue import WhereError


def _rows(cat):
    day = dt.datetime(2026, 11, 1)
    specs = [  # path, status, sample, load, start, meta
        ("/lab/a.h5", "success", "S3", 250.0, day + dt.timedelta(days=1), {"batch": "B7", "turns": "25"}),
        ("/lab/b.h5", "success", "S3", 150.0, day + dt.timedelta(days=2), {"batch": "B8", "turns": "x"}),
        ("/lab/c.h5", "failed", "S3", 300.0, day + dt.timedelta(days=3), {"batch": "b7-repeat"}),
        ("/lab/d.h5", "success", "S1", 500.0, day - dt.timedelta(days=5), {}),
        ("/lab/sub/e.h5", "success", "S3", 400.0, day + dt.timedelta(days=4), {"turns": "30"}),
    ]
    return {p: cat.upsert(dict(path=p, status=s, sample=smp, load_g=load, started=t, meta=m, plan="lifetime"))
            for p, s, smp, load, t, m in specs}


def test_rows_are_found_by_every_kind_of_condition(catalogue_url):
    with catalogue.open(catalogue_url) as cat:
        ids = _rows(cat)

        def found(*where, **kw):
            return sorted(r.path for r in cat.search(where, **kw))

        assert found("sample=S3", "load_g>=200") == ["/lab/a.h5", "/lab/c.h5", "/lab/sub/e.h5"]
        assert found("sample=S3", "load_g>=200", status="success") == ["/lab/a.h5", "/lab/sub/e.h5"]
        assert found("sample=S3", status="success", since="2026-11-01", until="2026-11-04") == [
            "/lab/a.h5", "/lab/b.h5"]
        assert found("batch~b7") == ["/lab/a.h5", "/lab/c.h5"]            # contains, any case
        assert found("batch=B7") == ["/lab/a.h5"]
        assert found("turns>=26") == ["/lab/sub/e.h5"]                    # a text "x" never matches a number
        assert found("turns<26") == ["/lab/a.h5"]
        assert found("load_g!=250", "load_g<400") == ["/lab/b.h5", "/lab/c.h5"]
        assert found(folder="/lab") == ["/lab/a.h5", "/lab/b.h5", "/lab/c.h5", "/lab/d.h5"]   # not below it
        newest = cat.search(limit=2)
        assert [r.path for r in newest] == ["/lab/sub/e.h5", "/lab/c.h5"]
        assert [r.path for r in cat.search(["turns>=0"], limit=1)] == ["/lab/sub/e.h5"]
        row = cat.get(ids["/lab/a.h5"])
        assert row.sample == "S3" and row.load_g == 250.0 and row.meta == {"batch": "B7", "turns": "25"}
        assert cat.by_path("/lab/a.h5").id == row.id and cat.get(10_000) is None
        assert json.loads(json.dumps(row.as_dict()))["started"] == "2026-11-02T00:00:00Z"
        # the same file registered again is the same row, updated
        again = cat.upsert(dict(path="/lab/a.h5", status="failed", reason="x"))
        assert again == row.id and cat.get(row.id).status == "failed" and cat.count() == 5
        assert cat.set_verdict("/lab/b.h5", "explained", "creep") == ids["/lab/b.h5"]
        assert found("verdict=explained") == ["/lab/b.h5"]
        assert cat.set_verdict("/lab/none.h5", "explained") is None


@pytest.mark.parametrize("expr,words", [
    ("load_g>=heavy", "load_g is a number"), ("started>=soon", "not a date"), ("sample", "FIELD OP VALUE"),
    ("batch>=B7", "compares numbers"), ("samples~3", "is a number"),
])
def test_a_bad_condition_is_named(tmp_path, expr, words):
    with catalogue.open(tmp_path) as cat:
        with pytest.raises(WhereError) as err:
            cat.search([expr])
    assert expr in str(err.value) and words in str(err.value)


def _register_many(url: str, who: str, n: int, barrier) -> None:
    cat = catalogue.open(url)
    barrier.wait()
    for i in range(n):
        run_id = cat.upsert(dict(path=f"/runs/{who}-{i:04d}.h5", status="running", rig=who, meta={"i": i}))
        cat.update(run_id, dict(status="success", samples=i, samples_lost=0, reason="all segments done"))
    cat.close()


def test_two_processes_registering_500_runs_each_at_once_lose_none(catalogue_url):
    catalogue.open(catalogue_url).close()   # the table exists before the race
    ctx = multiprocessing.get_context("spawn")
    barrier = ctx.Barrier(2)
    procs = [ctx.Process(target=_register_many, args=(catalogue_url, who, 500, barrier)) for who in ("A", "B")]
    for p in procs:
        p.start()
    for p in procs:
        p.join(300)
    assert [p.exitcode for p in procs] == [0, 0]
    with catalogue.open(catalogue_url) as cat:
        rows = cat.search()
    assert len(rows) == 1000 and len({r.id for r in rows}) == 1000
    for who in ("A", "B"):
        mine = sorted((r for r in rows if r.rig == who), key=lambda r: r.path)
        assert [r.path for r in mine] == [f"/runs/{who}-{i:04d}.h5" for i in range(500)]
        assert all(r.status == "success" and r.samples == r.meta["i"] and r.reason == "all segments done"
                   for r in mine)


def test_a_write_that_meets_a_lock_longer_than_the_busy_timeout_is_retried_not_lost(tmp_path, monkeypatch):
    """Another writer holds SQLite's write lock past the busy timeout (a slow host, a long
    rebuild): the registration waits and retries instead of failing the row."""
    import sqlite3
    import threading

    from tsa_bench.catalogue import database

    monkeypatch.setattr(database, "BUSY_TIMEOUT_S", 0.05)
    path = tmp_path / "catalogue.sqlite"
    with catalogue.open(str(path)) as cat:
        cat.upsert(dict(path="/lab/first.h5", status="success"))
        holder = sqlite3.connect(path, isolation_level=None, check_same_thread=False)
        holder.execute("BEGIN IMMEDIATE")   # the write lock, held well past 0.05 s
        released = threading.Timer(1.0, holder.execute, ("COMMIT",))
        released.start()
        try:
            run_id = cat.upsert(dict(path="/lab/second.h5", status="running"))
        finally:
            released.join()
            holder.close()
        assert cat.get(run_id).path == "/lab/second.h5" and cat.count() == 2
