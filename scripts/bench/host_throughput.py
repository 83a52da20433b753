#!/usr/bin/env python3
"""The host side of a lab at the ADS1115's limit: how many samples/s one core decodes and
stores, and four rigs at 860 samples/s each at once on this machine.

The device is the native firmware (firmware/native: the real core on a simulated board)
behind a pseudo-terminal, with the Arduino Mega bench file; the protocol samples at one
ADS1115 conversion (1163 us: 860 samples/s, SAMPLE_BLOCK frames).

1. Plain decode: the wire bytes of ``--decode-s`` s of device time (captured from the
   firmware), fed to the frame decoder and expanded into samples, on one core: samples/s.
2. Decode and store, end to end: ``tsa-bench run`` (bytes in over the pty; the link layer,
   the runner, the HDF5 run file, the live sidecar and the SQLite catalogue out) pinned to
   CPU 0, the firmware in virtual time (as fast as the host reads) pinned to CPU 1, for
   ``--store-s`` s of device time. Figure: samples per CPU second of the host process,
   after the CPU of the same command on a 1 s run (start-up, imports, handshake) is taken
   off; also the whole process's figure. Printed beside the plain decode figure and the
   86,000 samples/s target (100 rigs at 860/s).
3. Four rigs: four firmware processes in wall-clock time (``--speed 1``) and one
   ``tsa-bench lab`` with four serial rigs, each sampling at 860/s for ``--minutes`` of
   device time (default 10: that many minutes of wall time). Figures per rig: samples,
   samples/s of device time, counter gaps (from the stored counter column) and the run's
   ``samples_lost``; the load average before and after; the lab's CPU seconds.
   Exits 1 on any counter gap or a rig that did not succeed.

    nice -n 10 python3 scripts/bench/host_throughput.py [--minutes 10] [--store-s 600]
                                                        [--skip-rigs] [--keep DIR]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import subprocess
import sys
import tempfile
import time
import tty
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))
NATIVE = ROOT / "firmware" / "build" / "tsa_bench_native"
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "host")}
CLI = [sys.executable, "-m", "tsa_bench.cli"]
TARGET_SPS = 86_000
RIG_SPS = 860


@contextlib.contextmanager
def native_pty(*args: str, cpu: int | None = None) -> Iterator[str]:
    """The native firmware on a pty's master side; yields the slave's path (the port)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    pin = (lambda: os.sched_setaffinity(0, {cpu})) if cpu is not None else None
    proc = subprocess.Popen([str(NATIVE), *args], stdin=master, stdout=master, stderr=subprocess.DEVNULL,
                            close_fds=True, preexec_fn=pin)
    try:
        yield path
    finally:
        proc.kill()
        proc.wait(10)
        for fd in (master, slave):
            os.close(fd)


def write_inputs(folder: Path, hold_s: float) -> tuple[Path, Path]:
    """(bench file, protocol): the Mega bench with a short boot wait, a hold at 860 samples/s."""
    bench = folder / "mega.yaml"
    text = (ROOT / "configs" / "bench" / "arduino-mega.yaml").read_text()
    bench.write_text("\n".join(ln if not ln.startswith("boot_timeout_s:") else "boot_timeout_s: 0.2"
                               for ln in text.splitlines()) + "\n")
    protocol = folder / f"ads-860-{hold_s:g}s.yaml"
    protocol.write_text(f"name: ads-860\nsampling_period_s: 0.001163\nsteps:\n  - hold: {{duration_s: {hold_s:g}}}\n")
    return bench, protocol


class _Tee:
    """A serial port that keeps every byte it reads."""

    def __init__(self, port) -> None:
        self._port, self.received = port, bytearray()

    def read(self, size: int = 1) -> bytes:
        data = self._port.read(size)
        self.received += data
        return data

    def __getattr__(self, name: str):
        return getattr(self._port, name)


def plain_decode(folder: Path, seconds: float) -> tuple[float, int]:
    """(samples/s on one core, samples) of the frame decoder on captured wire bytes."""
    import serial

    from tsa_bench.bench import load_bench
    from tsa_bench.device import BenchClient
    from tsa_bench.plan import load_plan
    from tsa_bench.protocol import MessageDecoder
    from tsa_bench.protocol.blocks import expand
    from tsa_bench.runner import AutoOperator, Runner

    bench_file, protocol = write_inputs(folder, seconds)
    bench = load_bench(bench_file)
    with native_pty("--virtual") as port:
        ser = _Tee(serial.Serial(port, bench.baud, timeout=0.05, write_timeout=2.0))
        client = BenchClient(ser, ack_timeout_s=bench.ack_timeout_s, watchdog_s=bench.watchdog_s)
        client.connect(bench.boot_timeout_s, baud=bench.baud)
        Runner(client, load_plan(protocol, bench.limits), bench, [], AutoOperator(), backend="serial",
               port_name=port).run()
        ser.close()
    data = bytes(ser.received)
    os.sched_setaffinity(0, {0})
    best = float("inf")
    for _ in range(3):
        t0 = time.process_time()
        decoder, n = MessageDecoder(), 0
        for i in range(0, len(data), 4096):
            n += sum(type(m).__name__ == "Sample" for m in expand(f.message for f in decoder.feed(data[i:i + 4096])))
        best = min(best, time.process_time() - t0)
    os.sched_setaffinity(0, set(range(os.cpu_count() or 1)))
    return n / best, n


def host_run(folder: Path, hold_s: float, name: str) -> tuple[int, float, float]:
    """(samples stored, host CPU s, wall s) of `tsa-bench run` on CPU 0 against the firmware on CPU 1."""
    import h5py

    bench, protocol = write_inputs(folder, hold_s)
    out = folder / f"{name}.h5"
    with native_pty("--virtual", cpu=1) as port:
        t0 = time.monotonic()
        proc = subprocess.Popen(CLI + ["run", str(protocol), "--bench", str(bench), "--port", port, "--output",
                                       str(out), "--catalogue", str(folder / "catalogue.sqlite")],
                                env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                preexec_fn=lambda: os.sched_setaffinity(0, {0}))
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.monotonic() - t0
    if status != 0:
        raise SystemExit(f"run failed ({status}): {proc.stderr.read().decode()[-500:]}")
    with h5py.File(out, "r") as f:
        n = f["samples/t"].shape[0]
    return n, usage.ru_utime + usage.ru_stime, wall


def rigs(folder: Path, minutes: float) -> int:
    """Four rigs at 860/s for ``minutes`` of device time through one lab; returns the exit code."""
    import h5py
    import numpy as np

    bench, protocol = write_inputs(folder, minutes * 60)
    names = "ABCD"
    cpu0 = resource_children()
    with contextlib.ExitStack() as stack:
        ports = [stack.enter_context(native_pty("--speed", "1")) for _ in names]
        lab = folder / "four-rigs.yaml"
        lab.write_text("name: four-real-time-rigs\n"
                       f"defaults: {{protocol: {protocol}, bench: {bench}}}\nrigs:\n"
                       + "".join(f"  - {{name: {n}, port: {p}}}\n" for n, p in zip(names, ports)))
        load0 = os.getloadavg()
        t0 = time.monotonic()
        proc = subprocess.Popen(CLI + ["lab", str(lab), "--out", str(folder / "rigs")], env=ENV,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        samples_load = []
        while proc.poll() is None:
            time.sleep(30)
            samples_load.append(os.getloadavg()[0])
        out = proc.stdout.read()
        wall = time.monotonic() - t0
        load1 = os.getloadavg()
    cpu = resource_children() - cpu0
    print(f"\n4 rigs at {RIG_SPS} samples/s for {minutes:g} min of device time (native firmware, wall-clock time, "
          f"behind ptys; one tsa-bench lab): exit {proc.returncode}, wall {wall:.0f} s")
    print(f"  load average (1 min) before {load0[0]:.1f}, during {min(samples_load, default=0):.1f}.."
          f"{max(samples_load, default=0):.1f}, after {load1[0]:.1f}; CPU s of the lab, its runs and the firmware "
          f"processes: {cpu:.0f}")
    bad = proc.returncode != 0
    print(f"  {'rig':<4} {'status':<8} {'samples':>9} {'samples/s':>10} {'counter gaps':>13} {'samples_lost':>13}")
    for n in names:
        path = next((folder / "rigs").glob(f"*_{n}_ads-860.h5"))
        with h5py.File(path, "r") as f:
            counter = f["samples/counter"][()].astype(np.int64)
            t = f["samples/t"][()]
            gaps = int(np.clip(np.diff(counter) - 1, 0, None).sum())
            status, lost = str(f.attrs["exit_status"]), int(f.attrs["samples_lost"])
        rate = (len(t) - 1) / (t[-1] - t[0]) if len(t) > 1 else 0.0
        bad |= gaps > 0 or lost > 0 or status != "success"
        print(f"  {n:<4} {status:<8} {len(t):>9} {rate:>10.1f} {gaps:>13} {lost:>13}")
    if bad:
        print(out[-3000:])
    return 1 if bad else 0


def resource_children() -> float:
    import resource

    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--decode-s", type=float, default=120.0, help="device s of wire bytes for the plain decode")
    ap.add_argument("--store-s", type=float, default=600.0, help="device s of the decode+store run")
    ap.add_argument("--minutes", type=float, default=10.0, help="device (and wall) minutes of the four rigs")
    ap.add_argument("--skip-rigs", action="store_true", help="only the one-core figures")
    ap.add_argument("--keep", type=Path, help="keep the files here")
    args = ap.parse_args()
    if not NATIVE.exists():
        subprocess.run(["make", "-C", str(ROOT / "firmware"), "native"], check=True, stdout=subprocess.DEVNULL)
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} at start, "
              f"nice {os.nice(0)}")
        decode_sps, n_decoded = plain_decode(folder, args.decode_s)
        n0, cpu0, _ = host_run(folder, 1.0, "startup")
        n, cpu, wall = host_run(folder, args.store_s, "store")
        marginal = (n - n0) / (cpu - cpu0)
        print(f"\none core, SAMPLE_BLOCK frames at 860/s (load average now {os.getloadavg()[0]:.1f}):")
        print(f"  plain decode (frames -> samples)              {decode_sps:>10,.0f} samples/s   ({n_decoded} samples)")
        print(f"  decode + store end to end (bytes in, HDF5,    {marginal:>10,.0f} samples/s   ({n} samples, "
              f"{cpu:.2f} CPU s,")
        print(f"    live sidecar and catalogue out)                                        "
              f"{cpu0:.2f} CPU s of them start-up; wall {wall:.1f} s)")
        print(f"  the same, start-up included                   {n / cpu:>10,.0f} samples/s")
        print(f"  target (100 rigs at the ADS1115's 860/s)       {TARGET_SPS:>10,} samples/s")
        code = 0 if marginal >= TARGET_SPS else 1
        if not args.skip_rigs:
            code |= rigs(folder, args.minutes)
        return code


if __name__ == "__main__":
    sys.exit(main())
