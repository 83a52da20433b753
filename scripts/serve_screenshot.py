#!/usr/bin/env python3
"""The screenshot of the lab page in docs/lab.md, taken from real simulated runs.

Records two short runs (one succeeds, one loses its link and fails), then starts
``tsa-bench lab`` with the four rigs of configs/labs/four-sim-rigs.yaml (the lifetime
protocol at ``--speed`` times real time; rig D on a link that loses 1 % of the frames
towards the host, so its card shows sample-gap warnings), serves the page with
``tsa-bench serve``, waits until every rig is in its cycles, and has Debian's chromium
(Playwright, tests/web/browser.py) take the screenshot; then one Ctrl-C stops the lab.

    python3 scripts/serve_screenshot.py [--out docs/serve-page.png] [--speed 10]
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "host"))

from tests.catalogue.helpers import ENV, short_protocol, wait_for  # noqa: E402
from tests.faults.ptybench import quick_bench, relayed_sim  # noqa: E402
from tests.faults.relay import Faults, LinkFaults  # noqa: E402
from tests.web.browser import chromium, plot_state, serving  # noqa: E402

CLI = [sys.executable, "-m", "tsa_bench.cli"]


def _lab_file(folder: Path, speed: float, port_d: str, bench_d: Path) -> Path:
    text = (ROOT / "configs/labs/four-sim-rigs.yaml").read_text()
    for rig in "ABC":   # the simulations this lab runs go at `speed`; D's runs in this script
        text = text.replace(f"{{name: {rig}, ", f"{{name: {rig}, speed: {speed}, ")
    text = text.replace("{name: D, seed: 4,", f"{{name: D, port: {port_d}, bench: {bench_d},")
    path = folder / "lab.yaml"
    path.write_text(text)
    return path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "serve-page.png")
    parser.add_argument("--speed", type=float, default=10.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="tsa-screenshot-") as tmp:
        runs = Path(tmp) / "runs"
        runs.mkdir()
        protocol = short_protocol(Path(tmp))
        subprocess.run([*CLI, "run", str(protocol), "--out", str(runs), "--seed", "5", "--meta", "rig=E",
                        "--meta", "sample=S5"], env=ENV, check=True, capture_output=True)
        bench = quick_bench(Path(tmp))
        with relayed_sim(bench, speed=10.0, seed=6) as relay:
            failing = subprocess.Popen([*CLI, "run", str(protocol), "--out", str(runs), "--bench", str(bench),
                                        "--port", relay.path, "--meta", "rig=F", "--meta", "sample=S6"],
                                       env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            time.sleep(3)
            relay.link.faults.cut_at_s = relay.link.now_s()   # its cable is pulled
            failing.wait(timeout=300)
        with relayed_sim(bench, faults=LinkFaults(to_host=Faults(drop=0.01)), speed=args.speed, seed=4) as relay, \
                serving(runs, "--cache", str(Path(tmp) / "cache")) as url, chromium(1400, 1050) as page:
            lab = subprocess.Popen([*CLI, "lab", str(_lab_file(Path(tmp), args.speed, relay.path, bench)),
                                    "--out", str(runs)], env=ENV, stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True, text=True)
            try:
                page.goto(url)
                page.set_default_timeout(300_000)
                wait_for(lambda: page.locator("article.run").count() == 4 or lab.poll() is not None, "four rigs", 300)
                if lab.poll() is not None:
                    raise SystemExit(f"the lab ended early: {lab.stdout.read()}")
                files = page.locator("article.run").evaluate_all("cs => cs.map(c => c.dataset.runFile)")
                # past the 120 s rest at 15 turns and into the cycles on every rig
                wait_for(lambda: all(plot_state(page, f)[2] > 400 for f in files), "every rig in its cycles", 600)
                page.wait_for_function("document.querySelectorAll('#runs tbody tr').length >= 6")
                time.sleep(1.0)   # one more frame drawn
                args.out.parent.mkdir(parents=True, exist_ok=True)
                page.screenshot(path=str(args.out))
            finally:
                os.killpg(lab.pid, signal.SIGINT)   # one Ctrl-C stops every rig
                lab.wait(timeout=120)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
