"""The page's ASGI application (Starlette): the live board as server-sent events, the catalogue, figures.

Routes (all read-only; none changes a run, the catalogue or a rig):

* ``/``: the page (``static/index.html``; its script and style under ``/static/``).
* ``/api/live``: server-sent events. ``snapshot`` first (every run on the board, whole),
  then ``update`` (what changed each poll: :meth:`.board.Board.poll`). Each connection
  has a queue of at most :data:`QUEUE` updates; a connection that falls behind gets a
  fresh ``snapshot`` instead of a longer queue, so memory per connection is bounded.
* ``/api/runs?q=&status=&since=&limit=``: catalogue search (:mod:`.recent`).
* ``/api/runs/{id}``: one row and its report (:mod:`.figures`; drawn on first request).
* ``/figures/{key}/{name}``: a cached figure.
* ``/api/about``: what the server reads (runs folder, catalogue, its problem if any).

The board is polled every ``poll_s`` in a worker thread, the catalogue every
:data:`CATALOGUE_EVERY_S` in another: a slow database never delays the live view. Requests
whose Host is not the bound address are refused (``allowed_hosts``), so a web page elsewhere
cannot read the lab's runs through a browser on this machine (DNS rebinding).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import socket
import sys
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response, StreamingResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from tsa_bench.web.board import Board
from tsa_bench.web.figures import FigureCache
from tsa_bench.web.recent import CatalogueView, row_json

STATIC = Path(__file__).with_name("static")
QUEUE = 32
CATALOGUE_EVERY_S = 2.0
KEEPALIVE_S = 15.0
_RESYNC = object()
_HEADERS = {"Content-Security-Policy": "default-src 'self'; img-src 'self'; style-src 'self'; script-src 'self'",
            "X-Content-Type-Options": "nosniff", "Cache-Control": "no-store"}


def sse(event: str, data: Any) -> str:
    """One server-sent event (the payload is one line of JSON)."""
    return f"event: {event}\ndata: {json.dumps(data, separators=(',', ':'))}\n\n"


class Hub:
    """Fans each update out to every connection's bounded queue (module contract)."""

    def __init__(self) -> None:
        self.queues: set[asyncio.Queue] = set()

    def subscribe(self) -> asyncio.Queue:
        q: asyncio.Queue = asyncio.Queue(maxsize=QUEUE)
        self.queues.add(q)
        return q

    def unsubscribe(self, q: asyncio.Queue) -> None:
        self.queues.discard(q)

    def publish(self, updates: list[dict[str, Any]]) -> None:
        text = sse("update", {"runs": updates})
        for q in self.queues:
            if q.full():   # this page fell behind: it gets the whole board instead
                while not q.empty():
                    q.get_nowait()
                q.put_nowait(_RESYNC)
            else:
                q.put_nowait(text)


class Server:
    """The application's state: board, catalogue view, figure cache, hub, background tasks."""

    def __init__(self, runs_dir: Path | None, catalogue: str | None, cache_dir: Path, poll_s: float) -> None:
        self.runs_dir = runs_dir
        self.board = Board(runs_dir)
        self.view = CatalogueView(catalogue) if catalogue else None
        self.figures = FigureCache(cache_dir)
        self.hub = Hub()
        self.poll_s = poll_s
        self.host = socket.gethostname()

    async def _every(self, what, period_s: float) -> None:
        """``what`` in a worker thread every ``period_s``, its updates published; an error
        is said once on stderr and the loop goes on (the page must not freeze)."""
        said = set()
        while True:
            try:
                updates = await asyncio.to_thread(what)
            except Exception as exc:   # noqa: BLE001 (any: the page goes on, the problem is said)
                text = f"warning: tsa-bench serve: {what.__name__}: {type(exc).__name__}: {exc}"
                if text not in said:
                    said.add(text)
                    print(text, file=sys.stderr, flush=True)
                updates = []
            if updates:
                self.hub.publish(updates)
            await asyncio.sleep(period_s)

    async def poll_board(self) -> None:
        await self._every(self.board.poll, self.poll_s)

    async def poll_catalogue(self) -> None:
        await self._every(self._catalogue_facts, CATALOGUE_EVERY_S)

    def _catalogue_facts(self) -> list[dict[str, Any]]:
        """Sidecars of the catalogue's running rows onto the board; rig, sample, load and the
        end's reason of the runs on it."""
        if self.view is None:
            return []
        for row in self.view.running():
            if row.host == self.host:
                self.board.add_sidecar(row.live_path)
        updates = []
        for sidecar, (run_path, _status) in self.board.followed().items():
            row = self.view.by_path(run_path)
            if row is not None:
                info = {"id": row.id, "rig": row.rig, "sample": row.sample, "load_g": row.load_g,
                        "reason": row.reason if row.status != "running" else ""}
                update = self.board.set_info(sidecar, info)
                if update is not None:
                    updates.append(update)
        return updates

    # -- routes --------------------------------------------------------------
    async def index(self, request: Request) -> Response:
        return FileResponse(STATIC / "index.html", headers=_HEADERS)

    async def about(self, request: Request) -> Response:
        return JSONResponse({"runs_dir": str(self.runs_dir) if self.runs_dir else None,
                             "catalogue": self.view.shown if self.view else None,
                             "problem": self.view.problem if self.view else "no catalogue given"}, headers=_HEADERS)

    async def live(self, request: Request) -> Response:
        q = self.hub.subscribe()

        async def events() -> AsyncIterator[str]:
            try:
                yield sse("snapshot", {"runs": await asyncio.to_thread(self.board.snapshot)})
                while True:
                    try:
                        item = await asyncio.wait_for(q.get(), KEEPALIVE_S)
                    except asyncio.TimeoutError:
                        yield ": keep-alive\n\n"
                        continue
                    if item is _RESYNC:
                        yield sse("snapshot", {"runs": await asyncio.to_thread(self.board.snapshot)})
                    else:
                        yield item
            finally:
                self.hub.unsubscribe(q)

        return StreamingResponse(events(), media_type="text/event-stream",
                                 headers={**_HEADERS, "X-Accel-Buffering": "no"})

    async def runs(self, request: Request) -> Response:
        if self.view is None:
            return JSONResponse({"rows": [], "problem": "no catalogue given", "catalogue": None}, headers=_HEADERS)
        p = request.query_params
        try:
            limit = int(p.get("limit", "50"))
        except ValueError:
            return JSONResponse({"error": f"limit {p.get('limit')!r} is not a whole number"}, status_code=400,
                                headers=_HEADERS)
        found = await asyncio.to_thread(self.view.search, p.get("q", ""), p.get("status") or None,
                                        p.get("since") or None, limit)
        return JSONResponse(found, status_code=400 if "error" in found else 200, headers=_HEADERS)

    async def run(self, request: Request) -> Response:
        run_id = request.path_params["run_id"]
        row = await asyncio.to_thread(self.view.get, run_id) if self.view is not None else None
        if row is None:
            return JSONResponse({"error": f"no run {run_id} in the catalogue"}, status_code=404, headers=_HEADERS)
        report = await self.figures.report(row)
        if "key" in report:
            for fig in report.get("figures", []):
                fig["url"] = f"/figures/{report['key']}/{fig['file']}"
        return JSONResponse({"row": row_json(row), "report": report}, headers=_HEADERS)

    async def figure(self, request: Request) -> Response:
        path = self.figures.file(request.path_params["key"], request.path_params["name"])
        if path is None:
            return JSONResponse({"error": "no such figure"}, status_code=404, headers=_HEADERS)
        return FileResponse(path, media_type="image/png",
                            headers={**_HEADERS, "Cache-Control": "private, max-age=86400"})


def create_app(runs_dir: str | Path | None, catalogue: str | None, cache_dir: str | Path, *,
               poll_s: float = 0.25, allowed_hosts: list[str] | None = None) -> Starlette:
    """The page's application (module contract). ``allowed_hosts``: the Host names requests
    may carry (default: the loopback names)."""
    server = Server(Path(runs_dir) if runs_dir is not None else None, catalogue, Path(cache_dir), poll_s)

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette) -> AsyncIterator[None]:
        tasks = [asyncio.create_task(server.poll_board()), asyncio.create_task(server.poll_catalogue())]
        try:
            yield
        finally:
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
            server.board.close()
            if server.view is not None:
                server.view.close()

    routes = [
        Route("/", server.index),
        Route("/api/about", server.about),
        Route("/api/live", server.live),
        Route("/api/runs", server.runs),
        Route("/api/runs/{run_id:int}", server.run),
        Route("/figures/{key}/{name}", server.figure),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ]
    hosts = allowed_hosts or ["127.0.0.1", "localhost", "[::1]", "::1"]
    app = Starlette(routes=routes, lifespan=lifespan,
                    middleware=[Middleware(TrustedHostMiddleware, allowed_hosts=hosts)])
    app.state.server = server
    return app
