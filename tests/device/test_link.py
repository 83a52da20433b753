"""The link layer's sequencer: device frames in sequence order, each once."""

from __future__ import annotations

import random

from hypothesis import given, settings
from hypothesis import strategies as st

from tsa_bench.device.link import REMEMBER, FrameSequencer
from tsa_bench.protocol import Frame, msg


def frames(seqs):
    return [Frame(s % 65536, msg.Sample(s, s, 0, 0, 0, 0, 0, 0, 0)) for s in seqs]


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_a_swapped_pair_is_put_back_and_a_duplicate_dropped():
    seq = FrameSequencer(clock=Clock())
    out = seq.push(frames([1, 2, 4, 3, 3, 5, 5, 6]))
    assert [f.seq for f in out] == [1, 2, 3, 4, 5, 6]
    assert seq.stats.restored == 1 and seq.stats.duplicates == 2 and seq.stats.lost == 0


def test_a_gap_is_given_up_after_depth_frames_or_hold_time_and_late_frames_are_set_apart():
    clock = Clock()
    seq = FrameSequencer(depth=4, hold_s=0.05, clock=clock)
    assert [f.seq for f in seq.push(frames([10, 12, 13]))] == [10]  # waiting for 11
    clock.t = 0.06
    assert [f.seq for f in seq.push([])] == [12, 13]                # held long enough: 11 is lost
    assert seq.stats.lost == 1
    assert seq.push(frames([11])) == [] and [f.seq for f in seq.take_late()] == [11]
    assert [f.seq for f in seq.push(frames([15, 16, 17, 18]))] == [15, 16, 17, 18]  # 4 held: 14 given up
    assert seq.stats.lost == 2


def test_the_count_wraps_and_a_boot_restarts_it():
    seq = FrameSequencer(clock=Clock())
    assert [f.seq for f in seq.push(frames([65534, 65535, 0, 1]))] == [65534, 65535, 0, 1]
    boot = Frame(0, msg.Boot(0, 1, 0, 2))
    out = seq.push([boot] + frames([1, 2]))
    assert out[0].message == boot.message and [f.seq for f in out[1:]] == [1, 2] and seq.stats.restarts == 1


@settings(max_examples=200, deadline=None)
@given(n=st.integers(5, 300), seed=st.integers(0, 2**32), start=st.integers(0, 65535),
       drop=st.floats(0, 0.2), dup=st.floats(0, 0.2), swap=st.floats(0, 0.2))
def test_whatever_the_line_does_frames_come_out_in_order_once(n, seed, start, drop, dup, swap):
    """Drops, duplicates and adjacent swaps (a line's faults): the output is strictly
    increasing in sequence number, holds no frame twice, loses only dropped frames, and
    every sequence number is either released, late or counted lost."""
    rng = random.Random(seed)
    sent = list(range(start, start + n))
    line = []
    for s in sent:
        if rng.random() < drop:
            continue
        line.append(s)
        if rng.random() < dup:
            line.append(s)
    for i in range(len(line) - 1):
        if rng.random() < swap:
            line[i], line[i + 1] = line[i + 1], line[i]
    clock = Clock()
    seq = FrameSequencer(clock=clock)
    out = []
    for s in line:
        out += seq.push(frames([s]))
        clock.t += 0.001
    clock.t += 1.0
    out += seq.push([])
    got = [f.message.counter for f in out]  # unwrapped numbers
    late = [f.message.counter for f in seq.take_late()]
    assert got == sorted(set(got)), "not strictly increasing"
    assert set(got) <= set(line) and set(got) | set(late) == set(line)
    assert seq.stats.lost + len(got) >= got[-1] - got[0] + 1 if got else True


class OneByOne(FrameSequencer):
    """The sequencer without its bulk release of in-order runs: every frame takes the general path."""

    def _release_in_order(self, frames, out):
        return frames


@settings(max_examples=60, deadline=None)
@given(n=st.integers(5, 6000), seed=st.integers(0, 2**32), start=st.integers(0, 65535),
       drop=st.floats(0, 0.05), dup=st.floats(0, 0.05), swap=st.floats(0, 0.05), stale=st.floats(0, 0.02))
def test_in_order_runs_released_in_bulk_as_frame_by_frame(n, seed, start, drop, dup, swap, stale):
    """Batches of any size (the in-process port hands over many frames at once): the same
    frames come out, the same are late, the same counters, the same numbers remembered as
    released (more than the remembered window, so old duplicates are told from late frames)."""
    rng = random.Random(seed)
    line = []
    for s in range(start, start + n):
        if rng.random() < drop:
            continue
        line.append(s)
        if rng.random() < dup:
            line.append(s)
        if line and rng.random() < stale:
            line.append(max(start, s - rng.randrange(1, 5000)))  # an old frame repeated much later
    for i in range(len(line) - 1):
        if rng.random() < swap:
            line[i], line[i + 1] = line[i + 1], line[i]
    bulk, single = FrameSequencer(clock=Clock()), OneByOne(clock=Clock())
    got_bulk, got_single = [], []
    i = 0
    while i < len(line):
        k = rng.choice([1, 2, 3, 50, 700])
        got_bulk += bulk.push(frames(line[i:i + k]))
        for s in line[i:i + k]:
            got_single += single.push(frames([s]))
        i += k
    assert [f.message.counter for f in got_bulk] == [f.message.counter for f in got_single]
    assert [f.message.counter for f in bulk.take_late()] == [f.message.counter for f in single.take_late()]
    assert bulk.stats == single.stats
    assert bulk._released == single._released
    remembered = len(got_bulk) + bulk.stats.late          # numbers remembered as they came
    assert len(bulk._released) == min(REMEMBER, remembered)
    assert {f.seq for f in got_bulk[-100:]} <= bulk._released


def test_push_consecutive_releases_a_following_run_as_is_and_anything_else_as_push_does():
    seq = FrameSequencer(clock=Clock())
    assert [f.seq for f in seq.push_consecutive(frames([65534, 65535]))] == [65534, 65535]  # the first sets the count
    run = frames([0, 1, 2, 3])                                   # follows on across the wrap
    assert seq.push_consecutive(run) is run and seq.stats.released == 6
    assert [f.seq for f in seq.push_consecutive(frames([5, 6]))] == []   # 4 missing: held, as push holds it
    assert [f.seq for f in seq.push_consecutive(frames([4]))] == [4, 5, 6]
    assert seq.stats.restored == 2 and seq.stats.lost == 0
    assert [f.seq for f in seq.push_consecutive(frames([7, 9, 8]))] == [7, 8, 9]   # ends 2 apart, 3 frames
