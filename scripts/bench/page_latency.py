#!/usr/bin/env python3
"""How soon the lab page shows a run after its first samples are recorded (target: 1 s).

Serves the page (``tsa-bench serve``) into Debian's headless chromium (Playwright, as
tests/web does), then records ``--runs`` short simulated runs one after another at wall-clock
pace (``--speed 1``). For each run, two times on this machine's clock: when the first sample
reaches the run's live sidecar (a reader polling it every 5 ms, the earliest any reader can
see it) and when the page first draws a point of that run (a script in the page checking every
5 ms). Prints each latency, the median and the largest beside the 1 s target, with the load
average; exits 1 when the largest is over the target.

    nice -n 10 python3 scripts/bench/page_latency.py [--runs 5]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "host"))

from tests.catalogue.helpers import ENV, short_protocol, wait_for  # noqa: E402
from tests.web.browser import chromium, serving  # noqa: E402
from tsa_bench.store.live import LiveFormatError, LiveTail, sidecar_path  # noqa: E402

TARGET_MS = 1000.0
WATCH = """(file) => { window.__seen = window.__seen || {};
  const tick = () => {
    const c = document.querySelector(`article.run[data-run-file="${file}"] canvas[data-channel="length"]`);
    if (c && +(c.dataset.points || 0) > 0) { window.__seen[file] = Date.now(); return; }
    setTimeout(tick, 5);
  };
  tick(); }"""


def first_sample_ms(run_file: Path, stop: threading.Event, out: dict) -> None:
    """Wall time (ms since the epoch) when the sidecar first holds a sample."""
    side = sidecar_path(run_file)
    tail = None
    while not stop.is_set():
        if tail is None and side.is_file():
            try:
                tail = LiveTail(side)
            except (LiveFormatError, OSError):
                tail = None
        if tail is not None and len(tail.poll()):
            out["first"] = time.time() * 1000.0
            tail.close()
            return
        time.sleep(0.005)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}, nice {os.nice(0)}")
    latencies = []
    with tempfile.TemporaryDirectory(prefix="tsa-page-latency-") as tmp:
        runs = Path(tmp) / "runs"
        runs.mkdir()
        protocol = short_protocol(Path(tmp))
        with serving(runs) as url, chromium() as page:
            page.set_default_timeout(120_000)
            page.goto(url)
            page.wait_for_selector('#connection[data-state="live"]')
            for i in range(args.runs):
                name = f"latency-{i}.h5"
                page.evaluate(WATCH, name)
                stop, seen = threading.Event(), {}
                watcher = threading.Thread(target=first_sample_ms, args=(runs / name, stop, seen), daemon=True)
                watcher.start()
                run = subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", "run", str(protocol), "--output",
                                        str(runs / name), "--speed", "1", "--seed", str(i)], env=ENV,
                                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
                try:
                    shown = wait_for(lambda: page.evaluate(f"(window.__seen || {{}})['{name}']"),
                                     f"run {name} on the page", 120)
                    wait_for(lambda: "first" in seen, f"the first sample of {name}", 120)
                finally:
                    stop.set()
                    run.terminate()
                    run.wait(timeout=120)
                latency = float(shown) - seen["first"]
                latencies.append(latency)
                print(f"  run {i}: first sample in the sidecar -> first point on the page {latency:7.0f} ms")
    print(f"median {statistics.median(latencies):.0f} ms, largest {max(latencies):.0f} ms "
          f"(target {TARGET_MS:.0f} ms; load average now {os.getloadavg()[0]:.1f})")
    return 0 if max(latencies) <= TARGET_MS else 1


if __name__ == "__main__":
    sys.exit(main())
