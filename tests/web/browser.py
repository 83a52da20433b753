"""The lab page in a real browser for tests, benchmarks and the docs' screenshot.

:func:`chromium` launches Debian's ``/usr/bin/chromium`` through Playwright (never a
browser Playwright downloads) with the flags known to work on a headless CI box and a
fresh profile folder; :func:`serving` runs ``tsa-bench serve --port 0`` in a process of its
own and yields the URL it prints; :func:`runs_on_page` reads what the page shows.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from tests.catalogue.helpers import wait_for

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "host")}
CHROMIUM = Path("/usr/bin/chromium")
FLAGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
         "--disable-component-update", "--disable-sync"]


def why_no_browser() -> str | None:
    """Why the browser tests cannot run here, or None."""
    if not CHROMIUM.exists():
        return f"Debian's chromium is not installed at {CHROMIUM} (scripts/setup-test-services.sh installs it)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "playwright is not installed (pip install -e '.[dev]')"
    return None


@contextmanager
def chromium(width: int = 1400, height: int = 1000) -> Iterator:
    """A Playwright page in headless chromium, with a fresh profile folder."""
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory(prefix="tsa-chromium-") as profile, sync_playwright() as p:
        context = p.chromium.launch_persistent_context(
            profile, executable_path=str(CHROMIUM), headless=True, args=FLAGS,
            viewport={"width": width, "height": height})
        try:
            page = context.pages[0] if context.pages else context.new_page()
            yield page
        finally:
            context.close()


@contextmanager
def serving(runs_dir: Path, *extra: str) -> Iterator[str]:
    """``tsa-bench serve --runs DIR --port 0 EXTRA...``; yields its URL; Ctrl-C at the end."""
    proc = subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", "serve", "--runs", str(runs_dir), "--port", "0",
                             *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL,
                            text=True, env=ENV, cwd=ROOT)
    try:
        line = proc.stdout.readline()
        if "http://" not in line:
            proc.wait(timeout=30)
            raise AssertionError(f"tsa-bench serve did not start: {line}{proc.stderr.read()}")
        yield line.split("serving the lab page on ", 1)[1].split()[0]
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def page_until(page, expression: str, what: str, timeout_s: float = 120.0) -> None:
    """Until the JavaScript ``expression`` is true on the page (generous deadline). Polled from
    here with ``page.evaluate``: Playwright's ``wait_for_function`` polls by evaluating a string
    inside the page, which the page's Content Security Policy (no 'unsafe-eval') refuses."""
    wait_for(lambda: page.evaluate(f"() => Boolean({expression})"), what, timeout_s)


def card(page, run_file: str):
    """The live card of a run on the page (a Playwright locator)."""
    return page.locator(f'article.run[data-run-file="{run_file}"]')


def plot_state(page, run_file: str, channel: str = "length") -> tuple[str, int, float]:
    """(the card's status, points drawn, last t drawn in s) of one plot, as the page shows them."""
    return page.evaluate("""([file, channel]) => {
        const c = document.querySelector(`article.run[data-run-file="${file}"]`);
        if (!c) return ["", 0, -1];
        const canvas = c.querySelector(`canvas[data-channel="${channel}"]`);
        return [c.dataset.status || "", +(canvas.dataset.points || 0), canvas.dataset.lastT ? +canvas.dataset.lastT : -1];
    }""", [run_file, channel])
