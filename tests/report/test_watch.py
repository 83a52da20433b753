"""Live view: the sidecar written by `tsa-bench run`, read by `tsa-bench watch` while the
run records, after it finished, and after it was killed."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time

import numpy as np
from click.testing import CliRunner
from rich.console import Console

from tests.report.conftest import PROTOCOLS, ROOT, simulate
from tsa_bench.cli import main
from tsa_bench.console.watch import WatchState, watch
from tsa_bench.store import read_run
from tsa_bench.store.live import RECORD, LiveSidecar, LiveTail, sidecar_path

PROTO = {p.stem: p for p in PROTOCOLS}
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "host")}


class _Opens:
    """Counts the opens of one file by any process (Linux inotify, IN_OPEN)."""

    def __init__(self, path) -> None:
        import ctypes

        self._libc = ctypes.CDLL(None, use_errno=True)
        self._fd = self._libc.inotify_init1(os.O_NONBLOCK | os.O_CLOEXEC)
        assert self._fd >= 0, os.strerror(ctypes.get_errno())
        assert self._libc.inotify_add_watch(self._fd, str(path).encode(), 0x20) >= 0, os.strerror(ctypes.get_errno())
        self._n = 0

    def count(self) -> int:
        try:
            while data := os.read(self._fd, 4096):
                self._n += len(data) // 16     # struct inotify_event, no name for a watched file
        except BlockingIOError:
            pass
        return self._n

    def __enter__(self) -> "_Opens":
        return self

    def __exit__(self, *exc) -> None:
        os.close(self._fd)


def _cli(*args: str, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", *args], cwd=ROOT, env=ENV, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kw)


def test_sidecar_holds_exactly_the_recorded_samples(tmp_path):
    out = tmp_path / "run.h5"
    side = LiveSidecar(out, remove_at_end=False)
    simulate(PROTO["twist-sweep-3ply"], out, consumers=(side,))
    tail = LiveTail(sidecar_path(out))
    rec = tail.poll()
    run = read_run(out)
    assert tail.ended == "success" and int(tail.end_record["counter"]) == len(run) == len(rec)
    for name in RECORD.names[1:]:
        assert np.array_equal(rec[name], run.samples[name], equal_nan=True), name


def test_reader_takes_whole_records_and_whole_documents_only(tmp_path):
    """Torn anywhere (a writer killed mid-write, or a reader faster than it), the tail reads
    a prefix of the samples and of the documents, and the rest once it arrives."""
    out = tmp_path / "run.h5"
    side = LiveSidecar(out, remove_at_end=False)
    simulate(PROTO["stiffness-3ply"], out, consumers=(side,))
    data = sidecar_path(out).read_bytes()
    whole = LiveTail(sidecar_path(out), documents=True)
    samples = whole.poll()
    assert whole.ended == "success" and len(samples) == len(read_run(out)) and len(whole.segments) > 5
    size = RECORD.itemsize
    rng = np.random.default_rng(1)
    cuts = sorted(set(rng.integers(whole.offset - 40 * size, len(data), 60).tolist()) | {len(data) - size - 7})
    for cut in cuts:
        torn = tmp_path / "torn.h5.live"
        torn.write_bytes(data[:cut])
        tail = LiveTail(torn, documents=True)
        first = tail.poll()
        n_seg, n_ev = len(tail.segments), len(tail.events)
        assert tail.ended is None, cut
        np.testing.assert_array_equal(first, samples[:len(first)])
        assert tail.segments == whole.segments[:n_seg] and tail.events == whole.events[:n_ev]
        with open(torn, "ab") as f:   # the rest arrives later
            f.write(data[cut:])
        rest = tail.poll()
        np.testing.assert_array_equal(np.concatenate([first, rest]), samples)
        assert tail.segments == whole.segments and tail.events == whole.events and tail.ended == "success"
        tail.close()
    whole.close()


def test_a_sidecar_that_cannot_be_written_does_not_hurt_the_run(tmp_path, capfd):
    out = tmp_path / "run.h5"
    (tmp_path / "run.h5.live").mkdir()  # the sidecar's name is taken: it cannot be created
    simulate(PROTO["stiffness-3ply"], out, consumers=(LiveSidecar(out),))
    assert read_run(out).exit_status == "success" and len(read_run(out)) == 5399
    assert "live view disabled" in capfd.readouterr().err
    assert (tmp_path / "run.h5.live").is_dir() and sorted(p.name for p in tmp_path.iterdir()) == ["run.h5", "run.h5.live"]


def _readline(proc: subprocess.Popen, prefix: str, timeout_s: float = 60.0) -> str:
    """The next stdout line of ``proc`` starting with ``prefix`` (generous timeout: a loaded
    machine is slow, never wrong)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        ready, _, _ = select.select([proc.stdout], [], [], 0.5)
        if ready:
            line = proc.stdout.readline()
            if not line:
                raise AssertionError(f"{proc.args} ended before printing {prefix!r}: {proc.stderr.read()}")
            if line.startswith(prefix):
                return line.strip()
    raise AssertionError(f"{proc.args} printed no {prefix!r} line in {timeout_s} s")


def test_watch_follows_a_run_while_it_records(tmp_path):
    """The test moves the run on only after the watcher has shown the last step, so what
    the watcher sees does not depend on the machine's load."""
    out = tmp_path / "stepped.h5"
    writer = subprocess.Popen([sys.executable, "-m", "tests.report.stepped_writer", str(out)], cwd=ROOT, env=ENV,
                              text=True, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    w = None
    try:
        seen = []
        for step in range(3):
            writer.stdin.write("block\n")
            writer.stdin.flush()
            last_t = float(_readline(writer, "wrote ").split()[1])
            if w is None:
                w = _cli("watch", str(out), "--plain", "--interval", "0.05", "--wait", "60")
            while True:  # the watcher shows the run as it stands now, while it records
                line = _readline(w, "t=")
                t = float(line.split("t=")[1].split()[0])
                if t == last_t:
                    seen.append(line)
                    break
        writer.stdin.write("end\n")
        writer.stdin.flush()
        _readline(writer, "ended")
        rest, stderr = w.communicate(timeout=60)
        assert writer.wait(30) == 0 and w.returncode == 0, stderr
    finally:
        for p in (writer, w):
            if p is not None and p.poll() is None:
                p.kill()
    assert [s.split()[0] for s in seen] == ["t=9.00", "t=19.00", "t=29.00"]
    assert "samples=30" in seen[-1] and "segment 1/1" in seen[-1]
    assert rest.strip().splitlines()[-1] == f"run ended: success (all segments done); 30 samples; file {out}"
    assert not sidecar_path(out).exists()


def test_watch_waits_for_the_sidecar_of_a_run_that_is_starting(tmp_path):
    """A run creates its file a moment before its sidecar; a watcher that looks in
    between (the file exists, locked for writing, no sidecar yet) waits for the sidecar
    instead of calling the file unreadable."""
    out = tmp_path / "starting.h5"
    writer = subprocess.Popen([sys.executable, "-m", "tests.report.stepped_writer", str(out), "--sidecar-later"],
                              cwd=ROOT, env=ENV, text=True, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE)
    w = None
    try:
        _readline(writer, "run file open")
        with _Opens(out) as opens:
            w = _cli("watch", str(out), "--plain", "--interval", "0.05", "--wait", "60")
            # each look finds no sidecar and opens the run file to see it is being written:
            # 10 opens are several looks, whatever the machine's load
            deadline = time.monotonic() + 60
            while opens.count() < 10:
                assert w.poll() is None, w.communicate()
                assert time.monotonic() < deadline, f"the watcher looked {opens.count()} times in 60 s"
                time.sleep(0.05)
        assert w.poll() is None, w.communicate()
        writer.stdin.write("sidecar\nblock\nend\n")
        writer.stdin.flush()
        stdout, stderr = w.communicate(timeout=60)
        assert writer.wait(30) == 0
    finally:
        for p in (writer, w):
            if p is not None and p.poll() is None:
                p.kill()
    assert w.returncode == 0 and stdout.strip().splitlines()[-1].startswith("run ended: success"), stdout + stderr


def test_watch_and_run_together_end_with_the_run(tmp_path):
    """`run` and `watch` started together: whenever the watcher gets to look (while the
    run records or only after it ended), it ends with the run's outcome."""
    out = tmp_path / "live.h5"
    run = _cli("run", str(PROTO["stiffness-3ply"]), "--output", str(out))
    try:
        w = _cli("watch", str(out), "--plain", "--interval", "0.1", "--wait", "60")
        stdout, stderr = w.communicate(timeout=120)
        run.communicate(timeout=120)
    finally:
        for p in (run, w):
            if p.poll() is None:
                p.kill()
    assert run.returncode == 0 and w.returncode == 0, stderr
    lines = stdout.strip().splitlines()
    ts = [float(x.split("t=")[1].split()[0]) for x in lines if x.startswith("t=")]
    assert ts == sorted(ts), lines
    assert lines[-1].startswith("run ended: success (all segments done); 5399 samples"), lines
    assert not sidecar_path(out).exists()
    # a finished run: summarised from the closed file
    res = CliRunner().invoke(main, ["watch", str(out), "--once"])
    assert res.exit_code == 0 and "run ended: success" in res.output and "5399 samples" in res.output


def test_watch_says_a_killed_run_was_killed(tmp_path):
    out = tmp_path / "killed.h5"
    run = _cli("run", str(PROTO["lifetime"]), "--output", str(out), "--speed", "100")
    try:
        side = sidecar_path(out)
        deadline = time.monotonic() + 120
        while not (side.exists() and side.stat().st_size > 20_000):
            assert time.monotonic() < deadline, "no live samples"
            time.sleep(0.1)
        once = _cli("watch", str(out), "--once", "--plain")
        assert once.wait(30) == 0 and "run in progress" in once.stdout.read()
        run.send_signal(signal.SIGKILL)
        run.wait(10)
    finally:
        if run.poll() is None:
            run.kill()
    w = _cli("watch", str(out), "--plain", "--interval", "0.1")
    stdout, stderr = w.communicate(timeout=60)  # it must notice by itself, never wait forever
    assert w.returncode == 1 and "run was killed" in stdout, stdout + stderr
    side.unlink()  # without the sidecar, the file itself says it was never closed
    res = CliRunner().invoke(main, ["watch", str(out)])
    assert res.exit_code == 1 and "run was killed" in res.output and "never closed" in res.output


def _recorded_by_a_child(out) -> None:
    simulate(PROTO["stiffness-3ply"], out, consumers=(LiveSidecar(out, remove_at_end=False),))
    os._exit(0)


def test_a_journal_without_its_end_record_beside_a_closed_file_is_reported_as_the_file_ended(tmp_path):
    """A full disk can refuse the journal its end record after the run file was closed: the
    writer is gone, and `watch` reports how the file says the run ended, not a kill."""
    import multiprocessing

    out = tmp_path / "run.h5"
    child = multiprocessing.get_context("fork").Process(target=_recorded_by_a_child, args=(out,))
    child.start()
    child.join(120)
    assert child.exitcode == 0
    side = sidecar_path(out)
    with open(side, "r+b") as f:   # the end record was never written
        f.truncate(side.stat().st_size - RECORD.itemsize)
    w = _cli("watch", str(out), "--plain", "--interval", "0.1")
    stdout, stderr = w.communicate(timeout=60)
    assert w.returncode == 0 and "run ended: success (all segments done)" in stdout, stdout + stderr
    assert "killed" not in stdout


def test_watch_without_anything_to_watch(tmp_path):
    res = CliRunner().invoke(main, ["watch", str(tmp_path / "none.h5"), "--wait", "0"])
    assert res.exit_code == 2 and "no such run file" in res.output


def test_messages_are_never_wrapped_however_long_the_path(tmp_path):
    deep = tmp_path.joinpath(*(["a-folder-with-a-long-name"] * 8))
    deep.mkdir(parents=True)
    missing = deep / "no-such.h5"
    for width in (20, 80, 400):
        console = Console(width=width, force_terminal=False, record=True)
        assert watch(missing, plain=True, console=console) == 2
        text = console.export_text()
        assert f"error: {missing}: no such run file and no live sidecar" in text, text
        assert text.count("\n") == 1, text


def test_live_table_shows_latest_values():
    state = WatchState(n_segments=7)
    rec = np.zeros(3, dtype=RECORD)
    rec["t"] = [1.0, 1.1, 1.2]
    rec["length"] = [250.0, 251.0, 252.5]
    rec["resistance"] = [5.1, np.nan, np.nan]  # heater on: not measured, never the stale value from before
    rec["heater_voltage"] = [0.0, 3.0, 3.0]
    rec["segment"] = 2
    state.add(rec)
    console = Console(record=True, width=160)
    console.print(state.table("plan"))
    text = console.export_text()
    assert "252.50" in text and "not measured (heater on)" in text and "3/7" in text and "length" in text
    assert "5.1000" not in text
    assert "resistance=not measured (heater on)" in state.line() and "samples=3" in state.line()
    cooled = np.zeros(1, dtype=RECORD)
    cooled["t"], cooled["resistance"] = 1.3, 5.2
    state.add(cooled)
    assert "resistance=5.2000 ohm" in state.line()
