"""`tsa-bench serve` without a browser: the address it listens on, the Host it answers, what it
reads and writes, the figures it draws, and the bounds on its memory."""

from __future__ import annotations

import asyncio
import dataclasses
import fcntl
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from starlette.testclient import TestClient   # starlette and httpx are in [dev]: missing is an error, not a skip

from tests.catalogue.helpers import ENV, ROOT, short_protocol
from tsa_bench import catalogue
from tsa_bench.web import app as app_module
from tsa_bench.web.app import Hub, create_app
from tsa_bench.web.board import History, pick
from tsa_bench.web.figures import FigureCache
from tsa_bench.web.recent import CatalogueView
from tsa_bench.web.server import check_address, is_loopback, ServeError

@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> Path:
    """A folder with one finished simulated run and its catalogue."""
    folder = tmp_path_factory.mktemp("recorded")
    done = subprocess.run([sys.executable, "-m", "tsa_bench.cli", "run", str(short_protocol(folder)), "--output",
                           str(folder / "run.h5"), "--seed", "2", "--meta", "rig=R"], capture_output=True, text=True,
                          env=ENV, cwd=ROOT, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    return folder


def _client(runs: Path, cache: Path):
    return TestClient(create_app(runs, str(runs / "catalogue.sqlite"), cache),
                                           base_url="http://127.0.0.1")


def test_an_address_other_machines_reach_is_refused_unless_asked():
    for host in ("127.0.0.1", "127.0.0.2", "::1", "[::1]", "localhost"):
        assert is_loopback(host), host
        check_address(host, allow_remote=False)
    for host in ("0.0.0.0", "::", "192.168.1.20", "lab-pc.example.org"):
        assert not is_loopback(host), host
        with pytest.raises(ServeError, match="--allow-remote"):
            check_address(host, allow_remote=False)
        check_address(host, allow_remote=True)
    done = subprocess.run([sys.executable, "-m", "tsa_bench.cli", "serve", "--host", "0.0.0.0", "--port", "0"],
                          capture_output=True, text=True, env=ENV, cwd=ROOT, timeout=60)
    assert done.returncode == 2
    assert "refusing to listen on 0.0.0.0" in done.stderr and "--allow-remote" in done.stderr
    assert "Traceback" not in done.stderr and "serving" not in done.stdout


def test_a_request_naming_another_host_is_refused(recorded, tmp_path):
    with _client(recorded, tmp_path / "cache") as client:
        assert client.get("/api/about").status_code == 200
        assert client.get("/api/about", headers={"Host": "rebound.example.com"}).status_code == 400
        page = client.get("/")
        assert page.status_code == 200 and "tsa-bench lab" in page.text
        assert "script-src 'self'" in page.headers["content-security-policy"]


def test_the_catalogue_is_searched_and_never_created(recorded, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    view = CatalogueView(str(empty / "catalogue.sqlite"))
    found = view.search("sample=S3")
    assert found["rows"] == [] and "no catalogue yet" in found["problem"]
    assert not (empty / "catalogue.sqlite").exists()
    with _client(recorded, tmp_path / "cache") as client:
        rows = client.get("/api/runs", params={"q": "rig=R run.h5"}).json()["rows"]
        assert [r["name"] for r in rows] == ["run.h5"] and rows[0]["file_state"] == "ok"
        assert client.get("/api/runs", params={"q": "rig=nobody"}).json()["rows"] == []
        bad = client.get("/api/runs", params={"q": "load_g>=heavy"})
        assert bad.status_code == 400 and "load_g" in bad.json()["error"]


def test_figures_are_drawn_while_another_process_holds_the_run_file_locked(recorded, tmp_path):
    """A writer holding the run file (a --resume linking its continuation) is never made to
    fail by the page: the figures are read without HDF5's file lock."""
    fd = os.open(recorded / "run.h5", os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)   # as HDF5 does for a file open for writing
        with _client(recorded, tmp_path / "cache") as client:
            report = client.get("/api/runs/1").json()["report"]
            assert "unavailable" not in report, report
            names = [f["name"] for f in report["figures"]]
            assert "timeseries" in names
            png = client.get(report["figures"][0]["url"])
            assert png.status_code == 200 and png.content[:8] == b"\x89PNG\r\n\x1a\n"
            assert [e["kind"] for e in report["events"]].count("prompt") == 1
    finally:
        os.close(fd)


def test_figures_come_from_the_cache_and_nothing_else(recorded, tmp_path):
    cache = tmp_path / "cache"
    with _client(recorded, cache) as client:
        report = client.get("/api/runs/1").json()["report"]
        key = report["key"]
        before = (cache / key / "manifest.json").stat().st_mtime_ns
        assert client.get("/api/runs/1").json()["report"]["key"] == key   # cached: not drawn again
        assert (cache / key / "manifest.json").stat().st_mtime_ns == before
        for url in (f"/figures/{key}/index.html", f"/figures/{key}/manifest.json", f"/figures/{key}/..%2F..%2Fx.png",
                    "/figures/..%2F..%2F..%2Fetc/passwd", f"/figures/{key[:-1]}g/timeseries.png"):
            assert client.get(url).status_code == 404, url
        assert client.get("/api/runs/99").status_code == 404
        (cache / key / "stray.png").write_bytes(b"\x89PNG not a figure of the report")
        assert client.get(f"/figures/{key}/stray.png").status_code == 404   # only what the manifest lists
    assert sorted(p.name for p in cache.iterdir()) == [key]
    written = {p.name for p in recorded.iterdir()} - {"catalogue.sqlite-shm", "catalogue.sqlite-wal"}
    assert written == {"catalogue.sqlite", "run.h5", "short-life.yaml"}   # the page wrote nothing beside the runs


def test_a_run_being_recorded_or_changed_is_not_drawn(recorded, tmp_path):
    with catalogue.open(recorded) as cat:
        row = cat.get(1)
    cache = FigureCache(tmp_path / "cache")
    recording = dataclasses.replace(row, status="running", pid=os.getpid(), sha256=None)
    assert "still being recorded" in cache.why_not(recording)
    killed = dataclasses.replace(row, status="running", pid=2**22 + 12345, sha256=None)
    assert cache.why_not(killed) is None   # its writer is gone: its file is read as it stands
    copy = tmp_path / "changed.h5"
    shutil.copy(recorded / "run.h5", copy)
    changed = dataclasses.replace(row, path=str(copy))
    assert "changed since it was registered" in cache.why_not(changed)
    assert "missing" in cache.why_not(dataclasses.replace(row, path=str(tmp_path / "gone.h5")))


def test_a_page_that_falls_behind_gets_the_whole_board_not_a_longer_queue():
    hub = Hub()
    slow = hub.subscribe()
    for i in range(10 * app_module.QUEUE):
        hub.publish([{"key": "r1", "points": {"t": [float(i)]}}])
        assert slow.qsize() <= app_module.QUEUE
    items = []
    while not slow.empty():
        items.append(slow.get_nowait())
    assert app_module._RESYNC in items
    hub.unsubscribe(slow)
    hub.publish([{"key": "r1"}])   # nobody listens: nothing kept
    assert not hub.queues


def test_a_file_that_cannot_be_drawn_is_said_and_not_drawn_again_at_once(recorded, tmp_path):
    with catalogue.open(recorded) as cat:
        row = cat.get(1)
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not an HDF5 file\n" * 64)
    st = junk.stat()
    broken = dataclasses.replace(row, path=str(junk), size_bytes=st.st_size, mtime_ns=st.st_mtime_ns)
    assert broken.file_state() == "ok"
    cache = FigureCache(tmp_path / "cache")
    draws = []
    real_draw = cache._draw

    async def counted(*args):
        draws.append(args)
        return await real_draw(*args)

    cache._draw = counted

    async def twice():
        return await cache.report(broken), await cache.report(broken)

    first, second = asyncio.run(twice())
    assert first["unavailable"].startswith("cannot draw the figures: ") and "Traceback" not in first["unavailable"]
    assert second == first and len(draws) == 1   # remembered: a broken file is not drawn again on every click
    assert list((tmp_path / "cache").iterdir()) == []   # no half-written report left in the cache


def test_a_long_run_keeps_a_bounded_coarser_history():
    history = History(cap=100)
    for start in range(0, 10_000, 16):
        t = [float(x) for x in range(start, start + 16)]
        history.extend({"t": t, **{k: t for k in history.cols if k != "t"}})
        assert len(history) <= 100
    assert history.cols["t"][0] == 0.0 and history.cols["t"][-1] >= 9_900   # the whole run stays in view
    assert history.cols["t"][1] - history.cols["t"][0] >= 64   # its start at a coarser step (newest points as they come)
    assert all(len(v) == len(history) for v in history.cols.values())   # channels stay aligned with t
    for n, k in ((5, 16), (1000, 16), (17, 16)):
        idx = pick(n, k)
        assert len(idx) <= k and idx[-1] == n - 1 and len(set(idx)) == len(idx)


def test_the_board_takes_events_from_the_journal_newest_first_kept_and_bounded(tmp_path):
    """A storm of events in a run's journal reaches the page as at most MAX_EVENTS per poll
    (the newest), each detail cut to MAX_DETAIL_CHARS, beside the samples."""
    import numpy as np

    from tsa_bench.rundocs import SAMPLE_COLUMNS, EventRecord, RunStart, RunStop, SampleBlock
    from tsa_bench.store.live import LiveSidecar
    from tsa_bench.web import board as board_module
    from tsa_bench.web.board import Board

    run = tmp_path / "storm.h5"
    side = LiveSidecar(run)
    side.on_start(RunStart(plan_name="storm", protocol_text="", protocol_path=None, bench_text="", bench_path=None,
                           backend="sim", port="test", firmware="0.0.0", identity={}, n_segments=1,
                           estimated_duration_s=10.0))
    try:
        t = np.arange(10, dtype=float)
        cols = {name: np.zeros(10, dtype=dtype) for name, (dtype, _) in SAMPLE_COLUMNS.items()}
        cols.update(t=t, length=250.0 + t, counter=np.arange(10))
        side.on_samples(SampleBlock(cols))
        n = 3 * board_module.MAX_EVENTS
        for i in range(n):
            side.on_event(EventRecord(float(i), "sample_gap", f"gap {i} " + "x" * 5000))
        board = Board(tmp_path)
        (new,) = board.poll()
        events = new["events"]
        assert len(events) == board_module.MAX_EVENTS and events[-1]["t"] == float(n - 1)
        assert all(len(e["detail"]) == board_module.MAX_DETAIL_CHARS for e in events)
        assert all(e["severity"] == "warning" for e in events) and new["state"]["warnings"] == board_module.MAX_EVENTS
        assert new["state"]["samples"] == 10
        board.close()
    finally:
        side.on_stop(RunStop("success", "done", 10.0, 10, 0, 1, 0.1))
