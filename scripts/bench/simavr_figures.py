#!/usr/bin/env python3
"""Timing and safety figures of the real firmware ELF, measured in simavr with the emulated rig.

Prints, each from its own harness run (firmware/sim/, the figures from its JSON
summary, its trace of ADS1115 conversion starts and the frames the host received):
  * worst-case interrupt service times in cycles and us, per vector, over all runs
    (compare `make -C firmware isr-cycles`, the static worst case);
  * step rates: a --turns there-and-back move at each rate while sampling at
    --period-ms, with the move's duration against the planned trapezoid, samples lost,
    step-train underruns (the firmware's QUEUE_STATUS count and its EVENTs), the A4988's
    pulse checks and the SAMPLE timestamp error (|t_us - the conversion's real start|);
    a rate is "clean" with no underrun, no sample lost, no violation, every step counted
    and the timestamps within 100 us; the same at the device's shortest sampling period
    (single-shot, 3 ms): IDENTITY's max_rate_steps_per_s must not exceed the
    highest rate with every rate up to it clean there;
  * continuous sampling at 860 samples/s (one ADS1115 conversion) while moving at the
    top rate: every stamp against the emulated chip's true conversion start (max and mean
    |error|), the step position against the A4988's count then, samples lost;
  * a burst of 300 back-to-back HEARTBEATs during that move: step underruns, samples
    lost, heartbeats answered, UART bytes lost, the longest main-loop pass (max_pass_us);
  * sample-period jitter: intervals between the ADS1115 conversion starts, idle and at
    each rate;
  * the sampling floor: the device refuses a period 1 us below IDENTITY min_sample_period_us;
  * heater: the voltage actually applied (the gate's duty integrated on Timer2's
    (OCR2A + 1)/256 scale) against the request and against what SAMPLE reports;
  * host silent: heater off after the watchdog trip, motor and sense current released
    after the fault time;
  * UART throughput and the SAMPLE stream at the shortest period.

Exits 1 if any run shows a step underrun mid-move (the step train paused), a timestamp
error above 100 us (single-shot or continuous), a sample lost in the continuous runs, an applied heater voltage off by more than 2 % from 2 V up, the
heater still on 20 ms after the watchdog, IDENTITY advertising a rate not measured
clean at the shortest period, or a period below that floor accepted.

    python scripts/bench/simavr_figures.py [--period-ms 10] [--rates 1,2,3,4,5] [--turns 10]
"""

from __future__ import annotations

import argparse
import bisect
import dataclasses
import math
import sys
import time
from pathlib import Path

import serial

from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient
from tsa_bench.motion import TrapezoidProfile
from tsa_bench.protocol import encode, msg
from tsa_bench.protocol.blocks import ADS1115_CONVERSION_US, SINGLE_SHOT_MIN_PERIOD_US
from tsa_bench.bench.simavr_section import simavr_settings
from tsa_bench.simavr import SimavrBench

ROOT = Path(__file__).resolve().parents[2]
BENCH = load_bench(ROOT / "configs" / "bench" / "simavr.yaml")
SPT = BENCH.steps_per_turn
LINE_BYTES_PER_S = 250000 / 10
F_CPU = 16e6
STAMP_LIMIT_US = 100.0
HEATER_TOLERANCE = 0.02


class Session:
    """One harness run: the client, the frames received, and the summary at the end."""

    def __init__(self, build: bool, **settings) -> None:
        s = dataclasses.replace(simavr_settings(BENCH), build=build, trace=True, **settings)
        self.bench = SimavrBench(BENCH, s, seed=1)
        self.samples: list[msg.Sample] = []
        self.events: list[msg.Event] = []
        self.rx_bytes = 0

    def __enter__(self) -> "Session":
        self.bench.__enter__()
        self.port = serial.Serial(self.bench.port_path, 250000, timeout=0.02)
        self.bench.start()
        self.client = BenchClient(self.port, ack_timeout_s=1.0)
        self.identity = self.client.connect(10.0)
        self.client.set_position(0)
        return self

    def __exit__(self, *exc) -> None:
        self.port.close()
        self.bench.close()

    def command(self, message) -> None:
        self.client.command(message)
        self._keep(self.client.poll())

    def status(self) -> msg.QueueStatus:
        qs = self.client.status()
        self._keep(self.client.poll())
        return qs

    def _keep(self, messages) -> None:
        for m in messages:
            if isinstance(m, msg.Sample):
                self.samples.append(m)
                self.rx_bytes += len(encode(m, 0))
            elif isinstance(m, msg.Event):
                self.events.append(m)

    def run_until(self, done, timeout_s: float = 300.0, heartbeat: bool = True) -> None:
        deadline, beat = time.monotonic() + timeout_s, time.monotonic()
        while not done():
            if time.monotonic() > deadline:
                raise RuntimeError("timed out waiting for the device")
            if heartbeat and time.monotonic() - beat > 0.2:
                self.client.command(msg.Heartbeat())
                beat = time.monotonic()
            self._keep(self.client.poll())

    def wait_device_s(self, seconds: float) -> None:
        start = self.samples[-1].t_us if self.samples else 0
        self.run_until(lambda: bool(self.samples) and self.samples[-1].t_us >= start + seconds * 1e6)

    def segment_span_s(self, segment: int) -> float:
        t = {e.kind: e.t_us for e in self.events if e.segment == segment}
        return (t[msg.EventKind.SEGMENT_DONE] - t[msg.EventKind.SEGMENT_STARTED]) * 1e-6

    def stamp_errors_us(self, samples: list[msg.Sample]) -> list[float]:
        """|SAMPLE.t_us - the nearest ADS1115 conversion start| from the harness trace."""
        return [abs(err) for err, _ in self.stamp_and_step_errors(samples)]

    def stamp_and_step_errors(self, samples: list[msg.Sample]) -> list[tuple[float, int]]:
        """(SAMPLE.t_us - the nearest ADS1115 conversion start, its step position - the
        A4988's count at that start), from the harness trace."""
        rows = sorted((float(r[1]), int(r[2])) for r in (line.split() for line in
                      (self.bench.trace_text or "").splitlines()) if r and r[0] == "ads_start")
        starts = [t for t, _ in rows]
        out = []
        for s in samples:
            i = bisect.bisect_left(starts, s.t_us)
            j = min((k for k in (i - 1, i) if 0 <= k < len(starts)), key=lambda k: abs(starts[k] - s.t_us))
            out.append((s.t_us - starts[j], s.step_position - rows[j][1]))
        return out


def lost(samples: list[msg.Sample]) -> int:
    return sum(b.counter - a.counter - 1 for a, b in zip(samples, samples[1:]))


def jitter_row(label: str, s: dict, period_ms: float) -> str:
    iv = s["sample_interval"]
    return (f"{label:<26} {iv['count']:>6} {iv['mean_us'] / 1000:>9.3f} {iv['std_us']:>8.1f} "
            f"{(iv['min_us'] - period_ms * 1000):>+9.0f} {(iv['max_us'] - period_ms * 1000):>+9.0f}")


def rate_run(rate: float, period_us: int, turns: float, accel: float, build: bool = False) -> dict:
    steps, v, a = round(turns * SPT), round(rate * SPT), round(accel * SPT)
    with Session(build=build) as s:
        s.command(msg.SetSampling(1, period_us))
        s.wait_device_s(0.3)
        first = len(s.samples)
        s.command(msg.MoveBy(2, steps, v, a))
        s.command(msg.MoveBy(3, -steps, v, a))
        s.run_until(lambda: any(e.kind == msg.EventKind.SEGMENT_DONE and e.segment == 3 for e in s.events))
        s.wait_device_s(0.1)
        qs = s.status()
    planned = TrapezoidProfile(steps, v, a).duration
    actual = (s.segment_span_s(2) + s.segment_span_s(3)) / 2
    summ = s.bench.summary
    window = s.samples[first:]
    errors = s.stamp_errors_us(window)
    underrun_events = sum(e.kind == msg.EventKind.STEP_UNDERRUN for e in s.events)
    out = {"rate": rate, "v": v, "planned": planned, "actual": actual, "lost": lost(window),
           "underruns": qs.step_underruns, "underrun_events": underrun_events,
           "violations": sum(summ["violations"].values()), "steps": summ["steps"]["total"], "want_steps": 2 * steps,
           "stamp_max_us": max(errors), "stamp_mean_us": sum(errors) / len(errors), "summary": summ,
           "identity": s.identity}
    out["clean"] = (out["lost"] == 0 and out["underruns"] == 0 and out["underrun_events"] == 0
                    and out["violations"] == 0 and out["steps"] == out["want_steps"]
                    and out["stamp_max_us"] <= STAMP_LIMIT_US)
    return out


def rate_row(r: dict) -> str:
    err = 100 * (r["actual"] - r["planned"]) / r["planned"]
    return (f"{r['rate']:>6.1f} {r['v']:>8d} {r['planned']:>10.4f} {r['actual']:>10.4f} {err:>+8.3f} {r['lost']:>5d} "
            f"{r['underruns']:>5d} {r['steps']:>8d} {r['violations']:>5d} {r['stamp_mean_us']:>7.1f} "
            f"{r['stamp_max_us']:>7.1f}  {'yes' if r['clean'] else 'NO'}")


def continuous_run(turns: float, burst: int = 0) -> dict:
    """860 samples/s while moving there and back at the top rate; with ``burst`` that many
    HEARTBEATs back to back once the motor is at speed."""
    steps, v, a = round(turns * SPT), 16_000, 320_000
    with Session(build=False) as s:
        s.command(msg.SetSampling(1, ADS1115_CONVERSION_US))
        s.command(msg.MoveBy(2, steps, v, a))
        s.command(msg.MoveBy(3, -steps, v, a))
        answered = max_pass = 0
        if burst:
            s.run_until(lambda: sum(x.motor_moving for x in s.samples) > 200)
            s.port.write(b"".join(encode(msg.Heartbeat(), 1000 + i) for i in range(burst)))
        deadline = time.monotonic() + 300
        beat = time.monotonic()
        while not any(e.kind == msg.EventKind.SEGMENT_DONE and e.segment == 3 for e in s.events):
            if time.monotonic() > deadline:
                raise RuntimeError("timed out waiting for the device")
            got = s.client.poll()
            statuses = [m for m in got if isinstance(m, msg.QueueStatus)]
            answered += len(statuses)
            max_pass = max([max_pass] + [m.max_pass_us for m in statuses])
            s._keep(got)
            if time.monotonic() - beat > 0.2:
                s.client.command(msg.Heartbeat())
                beat = time.monotonic()
        qs = s.status()
    errors = s.stamp_and_step_errors(s.samples)
    t_err = [abs(e) for e, _ in errors]
    return {"samples": len(s.samples), "lost": lost(s.samples), "stamp_max_us": max(t_err),
            "stamp_mean_us": sum(t_err) / len(t_err), "step_max": max(abs(d) for _, d in errors),
            "underruns": qs.step_underruns, "max_pass_us": max(max_pass, qs.max_pass_us), "answered": answered,
            "uart_lost": qs.uart_overruns, "summary": s.bench.summary}


RATE_HEADER = (f"  {'turn/s':>6} {'steps/s':>8} {'planned s':>10} {'actual s':>10} {'err %':>8} {'lost':>5} "
               f"{'undr':>5} {'steps':>8} {'viol':>5} {'t err':>7} {'t max':>7}  clean")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--period-ms", type=float, default=10.0, help="sampling period while streaming (ms)")
    ap.add_argument("--rates", default="1,2,3,4,5", help="step rates to try, turns/s (5 = the firmware's limit)")
    ap.add_argument("--turns", type=float, default=10.0, help="length of each move (turns)")
    ap.add_argument("--accel", type=float, default=100.0, help="acceleration (turns/s^2)")
    args = ap.parse_args()
    period_us = round(args.period_ms * 1000)
    summaries: list[dict] = []
    jitter: list[str] = []
    failures: list[str] = []

    with Session(build=True) as s:                      # idle streaming
        s.command(msg.SetSampling(1, period_us))
        s.wait_device_s(5.0)
        ident = s.identity
    idle_errors = s.stamp_errors_us(s.samples)   # the trace is read when the harness has stopped
    summaries.append(s.bench.summary)
    jitter.append(jitter_row("idle", s.bench.summary, args.period_ms))

    rates = [float(r) for r in args.rates.split(",")]
    rate_results = []
    for rate in rates:
        r = rate_run(rate, period_us, args.turns, args.accel)
        rate_results.append(r)
        summaries.append(r["summary"])
        jitter.append(jitter_row(f"moving {rate:g} turn/s", r["summary"], args.period_ms))
    # the shortest single-shot period (each SAMPLE stamped at its conversion's start, checked
    # against the trace); shorter ones sample continuously: scripts/bench/wire_limit.py
    fastest = max(ident.min_sample_period_us, SINGLE_SHOT_MIN_PERIOD_US)
    floor = ident.min_sample_period_us
    fast_results = [rate_run(rate, fastest, args.turns, args.accel) for rate in rates]
    summaries += [r["summary"] for r in fast_results]
    for r in rate_results + fast_results:
        if r["underruns"] or r["underrun_events"]:
            failures.append(f"{r['underruns']} step underrun(s) mid-move at {r['v']} steps/s")
        if r["stamp_max_us"] > STAMP_LIMIT_US:
            failures.append(f"SAMPLE timestamp {r['stamp_max_us']:.0f} us off at {r['v']} steps/s")
    # the highest rate with every rate up to it clean at the shortest period
    clean_fast = 0
    for r in sorted(fast_results, key=lambda r: r["v"]):
        if not r["clean"]:
            break
        clean_fast = r["v"]

    cont = continuous_run(args.turns)                   # 860 samples/s at the top rate
    cont_burst = continuous_run(args.turns, burst=300)  # and a burst of heartbeats meanwhile
    summaries += [cont["summary"], cont_burst["summary"]]
    for r, what in ((cont, "continuous"), (cont_burst, "continuous with a 300-HEARTBEAT burst")):
        if r["stamp_max_us"] > STAMP_LIMIT_US:
            failures.append(f"{what}: SAMPLE timestamp {r['stamp_max_us']:.0f} us off")
        if r["lost"] or r["underruns"]:
            failures.append(f"{what}: {r['lost']} samples lost, {r['underruns']} step underruns")

    heater_rows = []
    with Session(build=False) as s:                     # heater: applied vs requested vs reported
        s.command(msg.SetSampling(1, 20_000))
        requests = [1000, 2000, 3300, 5000, 8000, 12000]
        reported = []
        for i, mV in enumerate(requests):
            s.command(msg.SetHeater(2 + 2 * i, mV))
            s.wait_device_s(0.4)
            reported.append(s.samples[-1].heater_mV)
            s.command(msg.SetHeater(3 + 2 * i, 0))
            s.wait_device_s(0.1)
    supply_V = BENCH.simavr["heater_supply_V"]
    for mV, got, p in zip(requests, reported, s.bench.summary["heater"]["periods"]):
        applied = supply_V * math.sqrt(p["mean_duty"])
        err = (applied - mV / 1000) / (mV / 1000)
        heater_rows.append(f"  {mV / 1000:>6.2f} V requested: {applied:>7.4f} V applied ({100 * err:+.2f} %), "
                           f"SAMPLE says {got / 1000:.3f} V ({100 * (got / 1000 - applied) / applied:+.2f} %)")
        if mV >= 2000 and abs(err) > HEATER_TOLERANCE:
            failures.append(f"heater {mV} mV applied {applied:.3f} V")
    summaries.append(s.bench.summary)

    with Session(build=False, host_gone_ms=300) as s:   # the host goes silent
        s.command(msg.SetSampling(1, 20_000))
        s.command(msg.SetHeater(2, 3000))
        s.run_until(lambda: any(e.kind == msg.EventKind.MOTOR_RELEASED for e in s.events), heartbeat=False)
    summ = s.bench.summary
    fault = next(e for e in s.events if e.kind == msg.EventKind.FAULT)
    tripped = fault.t_us * 1e-6 + summ["clock_zero_s"]
    heater_off_ms = (summ["heater"]["last_off_s"] - tripped) * 1e3
    release_s = summ["drive"]["last_disable_s"] - tripped
    sense_release_s = summ["drive"]["last_sense_off_s"] - tripped
    if not 0 <= heater_off_ms <= 20:
        failures.append(f"heater off {heater_off_ms:.1f} ms after the watchdog")
    summaries.append(summ)

    with Session(build=False) as s:                     # line saturation: a burst of replies
        s.port.write(b"".join(encode(msg.Heartbeat(), 1000 + i) for i in range(300)))
        deadline = time.monotonic() + 30
        answered = 0
        while answered < 300 and time.monotonic() < deadline:
            answered += sum(isinstance(m, msg.QueueStatus) for m in s.client.poll())
        time.sleep(0.2)
        qs = s.status()
    burst = s.bench.summary["uart"]
    summaries.append(s.bench.summary)

    with Session(build=False) as s:                     # the SAMPLE stream at the shortest period
        below = s.client.command(msg.SetSampling(1, floor - 1), check=False)
        s.command(msg.SetSampling(2, fastest))
        s.wait_device_s(0.3)
        first, bytes0 = len(s.samples), s.rx_bytes
        s.wait_device_s(2.0)
    if below.status == msg.Status.OK:
        failures.append(f"a {floor - 1} us sampling period accepted, below min_sample_period_us")
    window = s.samples[first:]
    span_s = (window[-1].t_us - s.samples[first - 1].t_us) * 1e-6
    throughput = (s.rx_bytes - bytes0) / span_s
    summaries.append(s.bench.summary)

    print(f"firmware ELF in simavr 1.6 (ATmega2560 at 16 MHz), emulated rig (TWI at TWBR's bit rate, "
          f"stk500v2 bootloader); sampling every {args.period_ms:g} ms\n")
    print("worst-case interrupt service (from vectoring to RETI; nested time included), all runs:")
    worst: dict[str, tuple[str, int, int]] = {}
    for summ in summaries:
        for vec, isr in summ["isr"].items():
            name, count, cyc = isr["name"], isr["count"], isr["max_cycles"]
            prev = worst.get(vec, (name, 0, 0))
            worst[vec] = (name, prev[1] + count, max(prev[2], cyc))
    print(f"  {'vector':<14} {'calls':>9} {'max cycles':>11} {'max us':>8}")
    for vec, (name, count, cyc) in sorted(worst.items(), key=lambda kv: int(kv[0])):
        print(f"  {name:<14} {count:>9d} {cyc:>11d} {cyc / F_CPU * 1e6:>8.2f}")
    print(f"\nstep rates: {args.turns:g} turns there and back at {args.accel:g} turns/s^2 while sampling every "
          f"{args.period_ms:g} ms (undr = step underruns mid-move; t err/max = SAMPLE timestamp error, us):")
    print(RATE_HEADER)
    for r in rate_results:
        print("  " + rate_row(r))
    print(f"\nthe same at the device's shortest sampling period, {fastest / 1000:g} ms:")
    print(RATE_HEADER)
    for r in fast_results:
        print("  " + rate_row(r))
    print(f"  highest clean rate at {fastest / 1000:g} ms sampling: {clean_fast:,} steps/s "
          f"({clean_fast / SPT:g} turns/s); IDENTITY advertises {ident.max_rate_steps_per_s:,} steps/s")
    if ident.max_rate_steps_per_s > clean_fast:
        failures.append(f"IDENTITY advertises {ident.max_rate_steps_per_s} steps/s, measured clean {clean_fast}")
    print(f"  idle SAMPLE timestamp error: mean {sum(idle_errors) / len(idle_errors):.1f} us, "
          f"max {max(idle_errors):.1f} us over {len(idle_errors)} samples")
    print(f"\ncontinuous sampling, one ADS1115 conversion ({ADS1115_CONVERSION_US} us), {args.turns:g} turns there "
          f"and back at 16,000 steps/s:")
    for r, what in ((cont, "plain"), (cont_burst, "300 HEARTBEATs back to back meanwhile")):
        print(f"  {what:<38} {r['samples']:>6} samples, {r['lost']} lost; stamp error vs the true conversion start "
              f"max {r['stamp_max_us']:.1f} us, mean {r['stamp_mean_us']:.1f} us; step position vs the A4988 at it "
              f"max {r['step_max']} steps; {r['underruns']} step underruns; longest main-loop pass (QUEUE_STATUS "
              f"max_pass_us) {r['max_pass_us']} us")
    print(f"  burst: {cont_burst['answered']} QUEUE_STATUS received (300 HEARTBEATs plus the host's own), "
          f"{cont_burst['uart_lost']} bytes the firmware's receiver dropped while its frames waited for the samples")
    print("\nsample-period jitter (intervals between ADS1115 conversion starts; deviation from the period):")
    print(f"  {'run':<26} {'count':>6} {'mean ms':>9} {'std us':>8} {'min us':>9} {'max us':>9}")
    for row in jitter:
        print("  " + row)
    top = max(fast_results, key=lambda r: r["v"])
    print(f"\nshortest single-shot period: {fastest / 1000:g} ms; moving at {top['v']} steps/s "
          f"there {top['lost']} slots skipped, {top['underruns']} underruns; sampling floor (IDENTITY "
          f"min_sample_period_us) {floor} us, {floor - 1} us "
          f"{'accepted' if below.status == msg.Status.OK else 'refused: ' + msg.Status(below.status).name.lower()}")
    print("\nheater: voltage applied (the gate's duty integrated on Timer2's (OCR2A+1)/256 scale, "
          f"{supply_V:g} V supply):")
    for row in heater_rows:
        print(row)
    print(f"\nhost silent (heater on, sampling): heater off {heater_off_ms:.2f} ms after the watchdog trip; "
          f"motor released {release_s:.3f} s and sense current off {sense_release_s:.3f} s after it "
          f"(fault_release_ms {ident.fault_release_ms})")
    rate = burst["tx_burst_bytes_per_s"]
    print(f"\nUART TX: longest back-to-back burst {burst['tx_longest_burst_bytes']:,} bytes at {rate:,.0f} bytes/s = "
          f"{100 * rate / LINE_BYTES_PER_S:.1f} % of the line's {LINE_BYTES_PER_S:,.0f} bytes/s; {answered} of the 300 "
          f"flooded heartbeats answered; the firmware counted {qs.uart_overruns} bytes lost in its receiver "
          f"(the host never has more than one command in flight)")
    slots = window[-1].counter - window[0].counter + 1
    print(f"SAMPLE stream at a {fastest / 1000:g} ms period, {span_s:.2f} s of device time: "
          f"{len(window) / span_s:,.0f} samples/s, {throughput:,.0f} bytes/s ({100 * throughput / LINE_BYTES_PER_S:.1f} "
          f"% of the line); {lost(window)} of {slots} slots skipped")
    if failures:
        print("\nFAILED: " + "; ".join(failures))
        return 1
    print("\nall clean: no step underrun, timestamps within 100 us, heater within 2 % from 2 V, heater off at the "
          "watchdog")
    return 0


if __name__ == "__main__":
    sys.exit(main())
