"""Timing of the simulated device (not a test): a 2.5 h virtual run at 10 Hz sampling.

Run: ``PYTHONPATH=host python tests/sim/timing_sim.py``. The host side mimics the
thesis' lifetime experiment (section 2.5.2): from 15 turns, MOVE_BY 2 turns then
DWELL 1 s, up to 25 turns and back, repeated; it keeps the queue topped up and
heartbeats every 0.5 s of device time. Only the device's calls are timed (receive,
advance, take_output: device + plant + sensors + encoding); host-side framing is not.
"""

from __future__ import annotations

import time

from tsa_bench.bench import load_bench
from tsa_bench.protocol import MessageDecoder, encode, msg
from tsa_bench.sim import SimDevice

VIRTUAL_S = 9000.0


def main() -> None:
    bench = load_bench(None)
    spt = bench.steps_per_turn
    dev = SimDevice(bench, seed=1)
    dec = MessageDecoder()
    seq = 0
    cpu = 0.0

    def send(m) -> None:
        nonlocal seq, cpu
        seq = (seq + 1) & 0xFFFF
        frame = encode(m, seq)
        t0 = time.process_time()
        dev.receive(frame)
        cpu += time.process_time() - t0

    rate, accel = int(200 / 60 * spt), 50 * spt
    segment, turns, direction = 0, 0, 1
    send(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH))
    send(msg.SetSampling(0, 100_000))
    send(msg.MoveTo(1, 15 * spt, rate, accel))
    turns, segment, queued, commands = 15, 2, 0, 3
    samples, last_hb = 0, 0.0
    while dev.now_s < VIRTUAL_S:
        while queued < 12:
            if not 15 <= turns + 2 * direction <= 25:
                direction = -direction
            send(msg.MoveBy(segment, 2 * direction * spt, rate, accel))
            send(msg.Dwell(segment + 1, 1_000_000))
            turns += 2 * direction
            segment, queued, commands = segment + 2, queued + 2, commands + 2
        if dev.now_s - last_hb >= 0.5:
            send(msg.Heartbeat())
            last_hb = dev.now_s
        t0 = time.process_time()
        dev.advance(0.5, 4096)
        out = dev.take_output()
        cpu += time.process_time() - t0
        for f in dec.feed(out):
            m = f.message
            if isinstance(m, msg.Sample):
                samples += 1
            elif isinstance(m, msg.Event) and m.kind == msg.EventKind.SEGMENT_DONE:
                queued -= 1
            elif isinstance(m, msg.Event) and m.kind == msg.EventKind.FAULT:
                raise SystemExit(f"fault {m}")
    print(f"virtual {dev.now_s:.0f} s, {samples} samples, {commands} commands, faults {dev.fault}")
    print(f"device CPU {cpu:.2f} s = {cpu / samples * 1e6:.1f} us per sample (all costs included)")


if __name__ == "__main__":
    main()
