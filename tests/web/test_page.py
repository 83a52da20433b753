"""The lab page in a real headless Chromium (Debian's, driven by Playwright) while simulated runs record.

Every wait is on a condition the page shows, with a generous deadline; nothing is timed.
"""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from tests.catalogue.helpers import ENV, ROOT, live_samples, short_protocol, wait_for
from tests.faults.ptybench import quick_bench, relayed_sim
from tests.faults.relay import Faults, LinkFaults
from tests.services import unavailable
from tests.web.browser import card, chromium, page_until, plot_state, serving, why_no_browser


@pytest.fixture(scope="module", autouse=True)
def _browser_here():
    """Skipped with the reason where Debian's chromium or playwright is missing; failed on CI."""
    why = why_no_browser()
    if why is not None:
        unavailable(why)

DEADLINE_MS = 120_000


@pytest.fixture(scope="module")
def page():
    with chromium() as p:
        p.set_default_timeout(DEADLINE_MS)
        yield p


def _run(tmp_path, name: str, *args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", "run", str(short_protocol(tmp_path)),
                             "--output", str(tmp_path / name), *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True, env=ENV, cwd=ROOT)


def _finish(proc: subprocess.Popen) -> str:
    try:
        out, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    return out + err


def test_the_page_loads_and_says_what_it_reads(page, tmp_path):
    with serving(tmp_path) as url:
        page.goto(url)
        page.wait_for_selector('#connection[data-state="live"]')
        assert page.locator("#no-live").is_visible()
        assert page.title() == "tsa-bench lab"
        page_until(page, "document.querySelector('#catalogue-problem').textContent.includes('no catalogue yet')",
                   "the page to say there is no catalogue yet")


def test_a_plot_updates_while_a_run_records_then_the_run_is_listed_with_its_figures(page, tmp_path):
    with serving(tmp_path) as url:
        page.goto(url)
        page.wait_for_selector('#connection[data-state="live"]')
        run = _run(tmp_path, "rig-a.h5", "--speed", "5", "--seed", "3", "--meta", "rig=A", "--meta", "sample=S7")
        try:
            first = wait_for(lambda: (s := plot_state(page, "rig-a.h5"))[0] == "running" and s[1] >= 3 and s,
                             "the run's card with a plot of its first samples")
            later = wait_for(lambda: (s := plot_state(page, "rig-a.h5"))[2] > first[2] + 2.0 and s,
                             "the plot to move on")
            assert later[0] == "running", f"the run ended before the page showed it move on: {first} -> {later}"
            assert later[1] > first[1]
            facts = card(page, "rig-a.h5").locator(".facts")
            assert "segment " in facts.inner_text() and " of " in facts.inner_text()
            card(page, "rig-a.h5").locator(".title").filter(has_text="A · short-life").wait_for()
            card(page, "rig-a.h5").locator('.badge[data-status="success"]').wait_for()
            assert "rig-a.h5" in _finish(run)
        finally:
            if run.poll() is None:
                run.kill()
        row = page.locator('#runs tbody tr[data-name="rig-a.h5"][data-status="success"]')
        row.wait_for()
        assert "S7" in row.inner_text()
        row.click()
        first_figure = page.locator("#figures figure img").first
        first_figure.wait_for()
        page_until(page, "[...document.querySelectorAll('#figures img')].every(i => i.complete && i.naturalWidth > 0)",
                   "every figure of the run to load")
        names = page.locator("#figures figure").evaluate_all("fs => fs.map(f => f.dataset.figure)")
        assert "timeseries" in names
        assert page.locator('#detail-events li[data-kind="prompt"]').count() == 1


def test_warnings_and_a_fault_show_as_they_happen(page, tmp_path):
    """Frames lost on the link give sample-gap warnings while the run records; then the
    cable is pulled and the run ends failed, with its reason, on the card and in the list."""
    bench = quick_bench(tmp_path)
    with relayed_sim(bench, faults=LinkFaults(to_host=Faults(drop=0.02)), speed=5.0, seed=4) as relay, \
            serving(tmp_path) as url:
        page.goto(url)
        page.wait_for_selector('#connection[data-state="live"]')
        run = _run(tmp_path, "rig-b.h5", "--bench", str(bench), "--port", relay.path, "--meta", "rig=B")
        try:
            b = card(page, "rig-b.h5")
            b.locator('ol.events li.warning[data-kind="sample_gap"]').first.wait_for()
            assert b.get_attribute("data-status") == "running"
            wait_for(lambda: live_samples(tmp_path / "rig-b.h5") > 20, "rig B's samples")
            relay.link.faults.cut_at_s = relay.link.now_s()     # B's cable is pulled
            b.locator('.badge[data-status="failed"]').wait_for()
            # the end's reason comes from the catalogue row the run completes as it closes
            b.locator(".reason").filter(has_text="failed: ").wait_for()
            reason = b.locator(".reason").inner_text()
            assert reason.startswith("failed: ") and len(reason.strip()) > len("failed:")
            assert "failed" in _finish(run)
        finally:
            if run.poll() is None:
                run.kill()
        # the list follows the catalogue: the row may show "running" until its next refresh
        row = page.locator('#runs tbody tr[data-name="rig-b.h5"][data-status="failed"]')
        row.wait_for(timeout=120_000)
        assert row.get_attribute("data-status") == "failed"
