"""The live events file beside the sidecar (``RUN.h5.live.events``), the page's feed of
warnings and faults: whole lines as they happen, bounded, readable to the end after the
writer deletes it, and a reader that never trusts a line."""

from __future__ import annotations

import json

from tsa_bench.rundocs import EventRecord, RunStart, RunStop
from tsa_bench.store import live
from tsa_bench.store.live import EventTail, LiveSidecar, events_path

START = RunStart(plan_name="events", protocol_text="", protocol_path=None, bench_text="", bench_path=None,
                 backend="sim", port="test", firmware="0.0.0", identity={}, n_segments=1, estimated_duration_s=10.0)


def test_each_event_is_readable_as_it_happens_and_after_the_end(tmp_path):
    run = tmp_path / "run.h5"
    side = LiveSidecar(run)
    side.on_start(START)
    assert events_path(run).exists()
    tail = EventTail(events_path(run))
    assert tail.poll() == []
    side.on_event(EventRecord(1.5, "sample_gap", "3 samples lost"))
    assert tail.poll() == [{"t": 1.5, "kind": "sample_gap", "detail": "3 samples lost"}]   # flushed at once
    side.on_event(EventRecord(float("nan"), "fault", "x" * 5000))
    side.on_stop(RunStop("failed", "fault", 2.0, 0, 0, 0, 0.1))
    assert not events_path(run).exists()   # removed at the end, as the sidecar is
    (fault,) = tail.poll()                  # the reader holding it still reads it to the end
    assert fault["t"] is None and fault["kind"] == "fault" and len(fault["detail"]) == live.MAX_DETAIL_CHARS
    tail.close()


def test_a_storm_of_events_cannot_fill_the_disk(tmp_path, monkeypatch):
    monkeypatch.setattr(live, "MAX_EVENTS", 20)
    run = tmp_path / "run.h5"
    side = LiveSidecar(run, remove_at_end=False)
    side.on_start(START)
    for i in range(500):
        side.on_event(EventRecord(float(i), "sample_gap", "lost"))
    side.on_stop(RunStop("success", "done", 500.0, 0, 0, 1, 0.1))
    lines = [json.loads(x) for x in events_path(run).read_text().splitlines()]
    assert len(lines) == 21 and lines[-1]["kind"] == "events_truncated" and "run file" in lines[-1]["detail"]


def test_the_reader_takes_whole_lines_and_says_what_it_cannot_read(tmp_path):
    path = tmp_path / "run.h5.live.events"
    with open(path, "wb") as f:
        tail = EventTail(path)
        f.write(b'{"t": 1, "kind": "warn", "detail": "a"}\n{"t": 2, "kin')
        f.flush()
        assert [e["t"] for e in tail.poll()] == [1.0]   # the half-written line waits
        f.write(b'd": "warn", "detail": "b"}\nnot json\n[1, 2]\n{"t": true, "kind": 7}\n')
        f.write(b"y" * (EventTail.MAX_LINE_BYTES + 10))
        f.flush()
        got = tail.poll()
    assert got[0] == {"t": 2.0, "kind": "warn", "detail": "b"}
    assert [e["kind"] for e in got[1:3]] == ["unreadable", "unreadable"]
    assert got[3] == {"t": None, "kind": "7", "detail": ""}
    assert got[4]["kind"] == "unreadable"   # a line that never ends is dropped, not kept growing
    assert tail.poll() == []
    tail.close()
