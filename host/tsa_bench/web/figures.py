"""Report figures of finished runs for the page: drawn once per file version, then cached.

Contract: :meth:`FigureCache.report` returns the manifest of a finished run's report
(:mod:`.render`), drawing it first when the cache has none for this version of the file
(its host, path, size, modification time and the registered SHA-256 name the version,
so a changed file is drawn again). Drawing runs in a child process
(``python -m tsa_bench.web.render``, HDF5 file locking off, at most one at a time, killed
after ``timeout_s``) so matplotlib never runs in the server and a bad file or a hung
draw costs one report, not the page. Two requests for one report share one draw. A run
still recording, or whose file is missing, changed since registration or on another host,
is not drawn: the manifest says why. :meth:`FigureCache.file` gives a cached figure by
key and name, nothing else: no path from a request ever reaches the file system.
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import os
import re
import sys
from pathlib import Path
from typing import Any

from tsa_bench import __version__
from tsa_bench.catalogue import RunRow

KEY = re.compile(r"^[0-9a-f]{20}$")
NAME = re.compile(r"^[a-z_]{1,40}\.png$")
#: Failed draws are remembered this long (s) before they are tried again.
RETRY_FAILED_S = 60.0


def recording(row: RunRow) -> bool:
    """The row's run is being recorded now: registered running by a process that is alive
    (a killed run stays "running" in the catalogue until a check; its file is readable)."""
    if row.status != "running":
        return False
    if row.file_state() == "elsewhere" or not isinstance(row.pid, int) or row.pid <= 0:
        return True   # cannot tell: do not touch it
    try:
        os.kill(row.pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


class FigureCache:
    """Figures of finished runs under ``folder`` (module contract)."""

    def __init__(self, folder: str | Path, *, dpi: int = 90, timeout_s: float = 300.0) -> None:
        self.folder = Path(folder)
        self.dpi = dpi
        self.timeout_s = timeout_s
        self._draws: dict[str, asyncio.Task] = {}
        self._failed: dict[str, tuple[float, str]] = {}
        self._one = asyncio.Semaphore(1)

    def key(self, row: RunRow) -> str | None:
        """The cache key of the row's file as it is now, or None when it cannot be drawn."""
        try:
            st = os.stat(row.path)
        except OSError:
            return None
        text = f"{__version__}|{self.dpi}|{row.host}|{row.path}|{st.st_size}|{st.st_mtime_ns}|{row.sha256}"
        return hashlib.sha256(text.encode()).hexdigest()[:20]

    def why_not(self, row: RunRow) -> str | None:
        """Why this run's figures are not drawn, or None when they can be."""
        state = row.file_state()
        if recording(row):
            return "the run is still being recorded: its live view is above; figures come when it ends"
        if state == "missing":
            return f"the run file {row.path} is missing"
        if state == "elsewhere":
            return f"the run file is on host {row.host}, not on this one"
        if state == "changed":
            return (f"the run file {row.path} changed since it was registered "
                    "(tsa-bench catalogue check; rebuild to register it again)")
        return None

    async def report(self, row: RunRow) -> dict[str, Any]:
        """The manifest with ``key`` (figure URLs: ``/figures/KEY/NAME``), or ``{"unavailable": why}``."""
        why = self.why_not(row)
        key = None if why else self.key(row)
        if key is None:
            return {"unavailable": why or f"the run file {row.path} cannot be read"}
        manifest = self._cached(key)
        if manifest is None:
            loop = asyncio.get_running_loop()
            failed = self._failed.get(key)
            if failed and loop.time() - failed[0] < RETRY_FAILED_S:
                return {"unavailable": failed[1]}
            task = self._draws.get(key)
            if task is None:
                task = self._draws[key] = asyncio.ensure_future(self._draw(row.path, key))
                task.add_done_callback(lambda _t, k=key: self._draws.pop(k, None))
            error = await asyncio.shield(task)
            if error:
                self._failed[key] = (loop.time(), error)
                return {"unavailable": error}
            manifest = self._cached(key)
            if manifest is None:
                return {"unavailable": "the figures were drawn but cannot be read from the cache"}
        return {**manifest, "key": key}

    def _cached(self, key: str) -> dict[str, Any] | None:
        try:
            data = json.loads((self.folder / key / "manifest.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        return data if isinstance(data, dict) else None

    async def _draw(self, run_path: str, key: str) -> str | None:
        """Draw into the cache; the error in one line, or None."""
        async with self._one:
            self.folder.mkdir(parents=True, exist_ok=True)
            env = {**os.environ, "HDF5_USE_FILE_LOCKING": "FALSE", "MPLBACKEND": "Agg"}
            proc = await asyncio.create_subprocess_exec(
                sys.executable, "-m", "tsa_bench.web.render", run_path, str(self.folder / key), str(self.dpi),
                stdin=asyncio.subprocess.DEVNULL, stdout=asyncio.subprocess.DEVNULL, stderr=asyncio.subprocess.PIPE,
                env=env)
            try:
                _, err = await asyncio.wait_for(proc.communicate(), self.timeout_s)
            except asyncio.TimeoutError:
                proc.kill()
                await proc.wait()
                return f"drawing the figures took more than {self.timeout_s:g} s; stopped"
            except asyncio.CancelledError:
                proc.kill()
                raise
            if proc.returncode != 0:
                lines = err.decode(errors="replace").strip().splitlines()
                return f"cannot draw the figures: {lines[-1] if lines else f'exit {proc.returncode}'}"
            return None

    def file(self, key: str, name: str) -> Path | None:
        """A cached figure (only a key and a name of the cache's own form), or None."""
        if not KEY.match(key) or not NAME.match(name):
            return None
        manifest = self._cached(key)
        if manifest is None or name not in {f.get("file") for f in manifest.get("figures", [])}:
            return None
        path = self.folder / key / name
        return path if path.is_file() else None
