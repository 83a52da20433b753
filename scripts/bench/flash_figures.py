#!/usr/bin/env python3
"""Figures of `make flash` through the Arduino Mega's own stk500v2 bootloader, on the
emulated Mega (`tsa-bench sim-serve --mega`: simavr at wall-clock pace, Debian's
stk500boot_v2_mega2560.hex, the port as the Mega's USB-serial chip).

Prints, from one emulated Mega (blank flash at power-on):
  * `make -C firmware flash PORT=...`: wall time, avrdude's own write and read-back
    (verify) times, the bytes, and the rate on the wire;
  * `tsa-bench check --port ...` on the firmware just flashed: wall time;
  * the bootloader's wait, reset to the application's start, in device time: after
    the host opened the port and after a hardware watchdog reset (a masked hang);
    and the wall time from that hang to the firmware's BOOT with the host quiet;
  * the same after a watchdog reset while the host keeps sending a HEARTBEAT every
    0.2 s for --talk-s: BOOT only 6-7 s after the host fell quiet (the bootloader takes
    any byte as the start of a programming session);
  * the whole chain (start, flash, check) in wall time.

    python scripts/bench/flash_figures.py [--talk-s 3]
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import time
from pathlib import Path

import serial

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT / "host"), str(ROOT)]

from tests import conformance_scenarios as sc  # noqa: E402
from tsa_bench.bench import load_bench  # noqa: E402
from tsa_bench.bench.simavr_section import SimavrSettings  # noqa: E402
from tsa_bench.protocol import encode, msg  # noqa: E402
from tsa_bench.simavr import SimavrBench, mega_settings  # noqa: E402


def boot_after(ex: sc.Exchange, since: int, talk_s: float = 0.0, timeout_s: float = 60.0) -> float:
    """Wall s until a BOOT arrives after index ``since``; a HEARTBEAT every 0.2 s for ``talk_s`` first."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < talk_s:
        ex.seq += 1
        ex.port.write(encode(msg.Heartbeat(), ex.seq))
        time.sleep(0.2)
        ex._read_some()
    while not any(isinstance(m, msg.Boot) for m in ex.received[since:]):
        if time.monotonic() - t0 > timeout_s:
            raise SystemExit("no BOOT")
        ex._read_some()
    return time.monotonic() - t0


def waits_after(summary: dict, cause: str) -> list[float]:
    """Device s from each reset of ``cause`` to the application's next start."""
    starts = summary["app_start_s"]
    return [min(t for t in starts if t > r["t_s"]) - r["t_s"] for r in summary["reset_log"]
            if r["cause"] == cause and any(t > r["t_s"] for t in starts)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--talk-s", type=float, default=3.0, help="host HEARTBEATs after the second watchdog reset")
    args = ap.parse_args()
    subprocess.run(["make", "-s", "-C", str(ROOT / "firmware"), "all", "harness"], check=True)
    bench = load_bench(ROOT / "configs" / "bench" / "simavr.yaml")
    settings = mega_settings(SimavrSettings(firmware_dir=ROOT / "firmware", build=False, hang_masked=True))
    t_chain = time.monotonic()
    with SimavrBench(bench, settings, seed=1) as mega:
        mega.start()
        t = time.monotonic()
        res = subprocess.run(["make", "-C", str(ROOT / "firmware"), "flash", f"PORT={mega.port_path}"],
                             capture_output=True, text=True)
        flash_s = time.monotonic() - t
        if res.returncode != 0:
            raise SystemExit(f"make flash failed:\n{res.stderr[-2000:]}")
        times = re.findall(r"\| 100% ([\d.]+)s", res.stderr)
        n = int(re.search(r"(\d+) bytes of flash verified", res.stderr).group(1))
        t = time.monotonic()
        res = subprocess.run([sys.executable, "-m", "tsa_bench.cli", "check", "--port", mega.port_path,
                              "--seconds", "1"], capture_output=True, text=True, cwd=ROOT)
        check_s = time.monotonic() - t
        chain_s = time.monotonic() - t_chain
        if res.returncode != 0:
            raise SystemExit(f"check failed:\n{res.stdout}{res.stderr}")
        with serial.Serial(mega.port_path, 250000, timeout=0.05) as port:
            ex = sc.Exchange(port, settle_s=0.08, first_reply_s=2.0)
            open_boot_s = boot_after(ex, 0)
            sc.handshake(ex)
            since = len(ex.received)
            mega.hang()
            quiet_s = boot_after(ex, since)
            sc.handshake(ex)
            since = len(ex.received)
            mega.hang()
            talked_s = boot_after(ex, since, args.talk_s)
    s = mega.summary
    print(f"make flash        {flash_s:6.2f} s wall: {n} bytes, avrdude write {times[0]} s + read-back {times[1]} s "
          f"({2 * n / (float(times[0]) + float(times[1])):.0f} bytes/s on the wire, both ways)")
    print(f"tsa-bench check   {check_s:6.2f} s wall (opens the port: reset, bootloader wait, BOOT, 1 s of samples)")
    print(f"chain             {chain_s:6.2f} s wall: start the emulated Mega, flash, verify, check")
    print(f"bootloader wait   {', '.join(f'{w:.4f}' for w in waits_after(s, 'external'))} s device time after "
          f"each opening of the port (the first: avrdude's session); {', '.join(f'{w:.4f}' for w in waits_after(s, 'watchdog'))} s after each "
          "watchdog reset")
    print(f"open -> BOOT      {open_boot_s:6.2f} s wall")
    print(f"hang -> BOOT      {quiet_s:6.2f} s wall, host quiet (two WDT periods, the bootloader's wait)")
    print(f"hang -> BOOT      {talked_s:6.2f} s wall, host sending HEARTBEATs for {args.talk_s:g} s: "
          f"{talked_s - args.talk_s:.2f} s after it fell quiet")
    causes = [r["cause"] for r in s["reset_log"]]
    print(f"reset log         {', '.join(causes)}")


if __name__ == "__main__":
    main()
