#!/usr/bin/env python3
"""The wire at the sensor's limit: the firmware ELF in simavr sampling at the ADS1115's
860 samples/s for a long stretch of device time.

One harness run (firmware/sim/, configs/bench/simavr.yaml): HELLO, the twist zero,
SET_SAMPLING at one ADS1115 conversion (1163 us: continuous mode, paced by the chip's
ALERT/RDY pin, SAMPLE_BLOCK frames), then the host reads and heartbeats until
``--minutes`` of device time have passed (with ``--move``, the motor meanwhile turns
there and back at the top rate, 5 turns/s, which loads the main loop most). Prints:

  * position samples per second of device time and the counter gaps (samples lost);
  * resistance words per second (the CS5513 at its own rate: the harness's converter
    makes one every 19,125 us, 612 clocks of its slowest 32 kHz on-chip oscillator,
    data sheet DS337 2.5.4: 52.3 words/s) and the share of samples carrying one;
  * line use: bytes received per second of device time against the 250 kbaud line's
    25,000 bytes/s, and bytes per sample (a SAMPLE frame takes 36);
  * the harness's ADS1115 conversions and ALERT/RDY pulses, UART overruns, step
    underruns and the worst ISR cycles per vector;
  * CPU seconds (user + sys, this process and the harness) and wall time.

Exits 1 on any counter gap, a sample rate off 860 by more than 0.5 %, a resistance
rate off the converter's by more than 5 %, or a UART overrun.

    python scripts/bench/wire_limit.py [--minutes 10] [--move] [--ads-rate-error 0]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import resource
import sys
import time
from pathlib import Path

import serial

from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient
from tsa_bench.protocol import msg
from tsa_bench.protocol.blocks import ADS1115_CONVERSION_US, ADS1115_SPS, SAMPLE_BYTES
from tsa_bench.bench.simavr_section import simavr_settings
from tsa_bench.simavr import SimavrBench

ROOT = Path(__file__).resolve().parents[2]
BENCH = load_bench(ROOT / "configs" / "bench" / "simavr.yaml")
LINE_BYTES_PER_S = 250000 / 10
NOT_MEASURED = int(msg.AdcFlags.RESISTANCE_NOT_MEASURED)


class CountingPort:
    """A pyserial port that counts the bytes read from it (the device's line use)."""

    def __init__(self, port: serial.Serial) -> None:
        self._port = port
        self.rx_bytes = 0

    def read(self, size: int = 1) -> bytes:
        data = self._port.read(size)
        self.rx_bytes += len(data)
        return data

    def __getattr__(self, name):
        return getattr(self._port, name)


def cpu_s() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0, help="device time to sample (default 10)")
    ap.add_argument("--move", action="store_true", help="turn the motor there and back at 5 turns/s meanwhile")
    ap.add_argument("--ads-rate-error", type=float, default=0.0,
                    help="the emulated ADS1115's oscillator error (+0.05: 5 %% slow; data sheet +-10 %%)")
    args = ap.parse_args()

    settings = dataclasses.replace(simavr_settings(BENCH), build=True, ads_rate_error=args.ads_rate_error, trace=True)
    wall0, cpu0 = time.monotonic(), cpu_s()
    with SimavrBench(BENCH, settings, seed=1) as bench:
        raw = serial.Serial(bench.port_path, 250000, timeout=0.02)
        port = CountingPort(raw)
        try:
            bench.start()
            client = BenchClient(port, ack_timeout_s=1.0)
            client.connect(10.0)
            client.set_position(0)
            client.command(msg.SetSampling(1, ADS1115_CONVERSION_US))
            n = gaps = words = invalid = max_pass = 0
            gap_at: list[tuple[int, float, int]] = []
            first = last = None
            t_start_us = t_words_from_us = None
            bytes_from = port.rx_bytes
            target_s = args.minutes * 60
            beat = time.monotonic()
            next_report = 60.0
            segment, there = 2, True
            spt = BENCH.steps_per_turn
            while True:
                for m in client.poll():
                    if isinstance(m, msg.Sample):
                        if first is None:
                            first, t_start_us = m, m.t_us
                            t_words_from_us = m.t_us + 200_000   # the CS5513's filter settles first
                            bytes_from = port.rx_bytes
                        elif last is not None:
                            gap = (m.counter - last.counter - 1) % 2**32
                            if gap:
                                gaps += gap
                                gap_at.append((gap, (m.t_us - t_start_us) / 1e6, m.motor_moving))
                        if t_words_from_us is not None and m.t_us >= t_words_from_us:
                            words += not m.adc_flags & NOT_MEASURED
                        n += 1
                        invalid += bool(m.adc_flags & msg.AdcFlags.POSITION_INVALID)
                        last = m
                    elif isinstance(m, msg.QueueStatus):
                        max_pass = max(max_pass, m.max_pass_us)
                    elif isinstance(m, msg.Event) and args.move and m.kind == msg.EventKind.QUEUE_EMPTY:
                        # the queue ran dry (SET_SAMPLING's, then each move's): the next move
                        target = 20 * spt if there else 0
                        client.command(msg.MoveTo(segment, target, 16_000, 320_000))
                        segment, there = segment + 1, not there
                if last is not None and (last.t_us - t_start_us) / 1e6 >= target_s:
                    break
                if last is not None and (last.t_us - t_start_us) / 1e6 >= next_report:
                    print(f"  ... {next_report / 60:g} min of device time, {n:,} samples, {gaps} gaps, "
                          f"{time.monotonic() - wall0:.0f} s wall", flush=True)
                    next_report += 60
                if time.monotonic() - beat > 0.2:
                    client.command(msg.Heartbeat())
                    beat = time.monotonic()
            rx = port.rx_bytes - bytes_from
            status = client.status()
            client.command(msg.SetSampling(0xFFFF, 0))
        finally:
            raw.close()
    summary = bench.summary or {}
    wall, cpu = time.monotonic() - wall0, cpu_s() - cpu0
    span_s = (last.t_us - t_start_us) / 1e6
    words_s = (last.t_us - t_words_from_us) / 1e6
    rate = (n - 1) / span_s
    word_rate = words / words_s
    expected_words = 1e6 / settings.cs5513_conversion_us
    adc = summary.get("adc", {})
    print(f"firmware ELF in simavr, ADS1115 in continuous mode at {ADS1115_SPS} SPS (oscillator error "
          f"{args.ads_rate_error:+.0%}), sampling period {ADS1115_CONVERSION_US} us"
          f"{', motor turning 0 <-> 20 turns at 16,000 steps/s' if args.move else ''}")
    print(f"  device time       {span_s:,.1f} s ({span_s / 60:.2f} min)")
    print(f"  position samples  {n:,}: {rate:,.2f} per s, counter gaps {gaps} (samples lost), "
          f"position invalid {invalid}")
    print(f"  resistance words  {words:,}: {word_rate:.2f} per s (CS5513 converter every "
          f"{settings.cs5513_conversion_us:,.0f} us: {expected_words:.2f} per s); "
          f"{words / max(1, n):.1%} of samples carry one")
    print(f"  line use          {rx / span_s:,.0f} bytes/s of {LINE_BYTES_PER_S:,.0f} ({rx / span_s / LINE_BYTES_PER_S:.1%}); "
          f"{rx / n:.1f} bytes/sample (a SAMPLE frame: {SAMPLE_BYTES})")
    print(f"  harness           ADS1115 conversions {adc.get('ads1115_conversions')}, ALERT/RDY pulses "
          f"{adc.get('ads1115_rdy_pulses')}, results never read {adc.get('ads1115_unread')}, longest wait from a "
          f"conversion's end to its read {adc.get('ads1115_read_latency_max_us')} us (a conversion lasts "
          f"{1e6 / ADS1115_SPS:.0f}); UART RX overruns {summary.get('violations', {}).get('uart_rx_overrun')}; "
          f"step underruns {status.step_underruns}; I2C bus recoveries {status.i2c_recoveries}")
    print(f"  firmware          longest main-loop pass {max(max_pass, status.max_pass_us):,} us (QUEUE_STATUS "
          f"max_pass_us); ADS1115 conversion period measured {status.sensor_period_ns / 1000:.3f} us; "
          f"sensor restarts {status.sensor_restarts}")
    isr = summary.get("isr", {})
    if isr:
        worst = ", ".join(f"{v['name'] if v['name'] != '?' else 'vector ' + k} {v['max_cycles']}"
                          for k, v in sorted(isr.items(), key=lambda kv: int(kv[0])))
        print(f"  worst ISR cycles  {worst}")
    print(f"  cost              wall {wall:,.1f} s, CPU {cpu:,.1f} s (user+sys, host and harness); "
          f"{span_s / wall:.2f}x real time")
    if gap_at:
        print("  gaps (samples lost, device s, moving): " + ", ".join(f"{g} at {t:.3f} s{' moving' if mv else ''}"
                                                               for g, t, mv in gap_at[:10]))
    unread = [line.split() for line in (bench.trace_text or "").splitlines() if line.startswith("ads_unread")]
    if unread:
        print("  unread results (device us, the AVR's PC when the next one replaced it: "
              "avr-addr2line -f -e firmware/build/tsa_bench.elf): "
              + ", ".join(f"{u[1]} pc {u[3]}" for u in unread[:10]))
    failures = []
    if gaps:
        failures.append(f"{gaps} counter gaps")
    nominal = ADS1115_SPS / (1 + args.ads_rate_error)
    if abs(rate / nominal - 1) > 0.005:
        failures.append(f"{rate:.2f} samples/s, expected {nominal:.2f}")
    if abs(word_rate / expected_words - 1) > 0.05:
        failures.append(f"{word_rate:.2f} resistance words/s, expected {expected_words:.2f}")
    if summary.get("violations", {}).get("uart_rx_overrun"):
        failures.append("UART RX overruns")
    for f in failures:
        print(f"FAIL: {f}", file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    sys.exit(main())
