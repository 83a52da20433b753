"""The simulated bench on a pseudo-terminal behind a fault-injecting relay: a real serial
link for a host in this process or in another (`tsa-bench run --port`)."""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from tests.faults.relay import LinkFaults, PtyRelay
from tsa_bench.bench import load_bench
from tsa_bench.transport.pty_server import serve_pty

ROOT = Path(__file__).resolve().parents[2]


def quick_bench(tmp_path: Path) -> Path:
    """configs/bench/sim.yaml with a short boot wait: a pty client never sees the BOOT
    the server sent when it started, so it would wait the full 3 s for nothing."""
    text = (ROOT / "configs/bench/sim.yaml").read_text().replace("boot_timeout_s: 3.0", "boot_timeout_s: 0.2")
    path = tmp_path / "pty-bench.yaml"
    path.write_text(text)
    return path


@contextmanager
def relayed_sim(bench_path: Path, faults: LinkFaults = LinkFaults(), speed: float | None = None,
                seed: int = 1) -> Iterator[PtyRelay]:
    """``serve_pty`` in a thread, a :class:`PtyRelay` in front of it; yields the relay
    (host side: ``relay.path``; what crossed it: ``relay.link``)."""
    ready: queue.Queue[str] = queue.Queue()
    stop = threading.Event()
    server = threading.Thread(target=serve_pty, args=(load_bench(bench_path), speed, seed, ready.put, stop),
                              daemon=True)
    server.start()
    relay = PtyRelay(ready.get(timeout=10), faults)
    try:
        yield relay
    finally:
        relay.close()
        stop.set()
        server.join(timeout=10)
