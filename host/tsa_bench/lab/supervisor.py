"""Several rigs at once: one ``tsa-bench run`` process per rig, one terminal, one Ctrl-C.

Units: device time in s, loads in g.

Why a process per rig (not a thread): each rig then runs exactly the ``run`` command a
person would type (the same runner, writer, live sidecar, catalogue registration, exit
codes and Ctrl-C handling, so a lab run is the same file as a single run); one rig's
crash, lost link or broken HDF5 library (which ends its process at once) cannot touch
another; and the rigs' simulations and decoders use both cores instead of sharing one
interpreter lock.

Contract of :class:`Supervisor` (``run``):

* Each rig's process starts in a process group of its own, so the terminal's Ctrl-C
  reaches only the supervisor. The supervisor passes every SIGINT or SIGTERM it gets on
  to every rig still running: each sends STOP and closes its file "aborted" (a second
  one hurries them, as in ``run``). A signal before all rigs started starts no more.
* A rig's operator prompts come over its socket (:mod:`.channel`) and are asked one at a
  time on the terminal, naming the rig; while a person is asked, the other rigs' output
  waits, so nothing is written into a question. Ctrl-C at a prompt aborts every rig.
  Without a terminal input (closed stdin), a question is answered "nobody can answer",
  and that rig fails without stopping the others.
* A rig's output lines are shown whole, each prefixed with ``[rig]``.
* A rig that fails, loses its link or dies leaves the others running.
* The result is one :class:`RigResult` per rig, read from its run file at the end.
"""

from __future__ import annotations

import datetime as dt
import os
import queue
import re
import signal
import socket
import subprocess
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import tsa_bench
from tsa_bench.lab.channel import decode, encode
from tsa_bench.lab.labfile import Lab, Rig
from tsa_bench.runner.interrupts import Interrupts

YES = ("y", "yes")
#: How often the supervisor looks at signals while nothing happens (s of wall time).
POLL_S = 0.2


@dataclass
class RigResult:
    """How one rig's run ended."""

    rig: str
    path: Path
    exit_code: int | None          # the run process's (negative: killed by that signal); None: never started
    status: str                    # the file's exit status, "killed", "not started" or "no file"
    samples: int = 0
    samples_lost: int | None = None
    device_time_s: float | None = None
    reason: str = ""


def out_path(out_dir: Path, stamp: str, rig: Rig) -> Path:
    safe = re.sub(r"[^A-Za-z0-9_.-]+", "-", rig.plan_name).strip("-") or "run"
    return out_dir / f"{stamp}_{rig.name}_{safe}.h5"


def _line_out(text: str) -> None:
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def _terminal_ask(text: str) -> str | None:
    """The line a person typed after ``text``; None when the input is closed."""
    sys.stdout.write(text)
    sys.stdout.flush()
    line = sys.stdin.readline()
    return line.rstrip("\r\n") if line else None


class _Worker:
    def __init__(self, rig: Rig, path: Path) -> None:
        self.rig, self.path = rig, path
        self.proc: subprocess.Popen[bytes] | None = None
        self.sock: socket.socket | None = None
        self.exit_code: int | None = None
        self.last_error = ""


class Supervisor:
    """See the module contract."""

    def __init__(self, lab: Lab, out_dir: str | Path, *, catalogue: str | None = None, allow_url: bool = False,
                 trust_firmware_dir: bool = False, out: Callable[[str], None] = _line_out,
                 ask: Callable[[str], str | None] = _terminal_ask, stamp: str | None = None) -> None:
        self.lab, self.out_dir = lab, Path(out_dir)
        self.catalogue, self.allow_url, self.trust_firmware_dir = catalogue, allow_url, trust_firmware_dir
        self.out, self.ask = out, ask
        stamp = stamp or dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        self.workers = [_Worker(r, out_path(self.out_dir, stamp, r)) for r in lab.rigs]
        self.interrupts = Interrupts()
        self._events: queue.Queue[tuple[str, _Worker, Any]] = queue.Queue()
        self._forwarded = 0
        self._width = max(len(r.name) for r in lab.rigs)

    # -- starting ------------------------------------------------------------
    def taken_paths(self) -> list[Path]:
        """Run files that already exist (never overwritten: the lab refuses to start)."""
        return [w.path for w in self.workers if w.path.exists() or w.path.is_symlink()]

    def _argv(self, w: _Worker, fd: int) -> list[str]:
        rig = w.rig
        argv = [sys.executable, "-m", "tsa_bench.cli", "run", str(rig.protocol), "--bench", str(rig.bench),
                "--output", str(w.path), "--operator-socket", str(fd)]
        if rig.port is not None:
            argv += ["--port", rig.port]
        if rig.seed is not None:
            argv += ["--seed", str(rig.seed)]
        if rig.speed is not None:
            argv += ["--speed", repr(rig.speed)]
        for name, value in rig.variables.items():
            argv += ["--set", f"{name}={value}"]
        for key, value in {"lab": self.lab.name, "rig": rig.name, **rig.meta}.items():
            argv += ["--meta", f"{key}={value}"]
        if self.catalogue is not None:
            argv += ["--catalogue", self.catalogue]
        if self.allow_url:
            argv.append("--allow-url")
        if self.trust_firmware_dir:
            argv.append("--trust-firmware-dir")
        return argv

    def _start(self, w: _Worker) -> None:
        ours, theirs = socket.socketpair()
        package_root = str(Path(tsa_bench.__file__).resolve().parents[1])
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(
            [package_root] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])}
        try:
            w.proc = subprocess.Popen(self._argv(w, theirs.fileno()), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                      stderr=subprocess.PIPE, pass_fds=(theirs.fileno(),), process_group=0, env=env)
        except OSError as exc:
            ours.close()
            w.last_error = f"could not start: {exc}"
            return
        finally:
            theirs.close()
        w.sock = ours
        err = threading.Thread(target=self._pump_lines, args=(w, w.proc.stderr, "err"), daemon=True)
        err.start()
        threading.Thread(target=self._pump_lines, args=(w, w.proc.stdout, "out", err), daemon=True).start()
        threading.Thread(target=self._pump_socket, args=(w,), daemon=True).start()

    # -- the threads (they only queue) ---------------------------------------------
    def _pump_lines(self, w: _Worker, stream: IO[bytes], which: str, other: threading.Thread | None = None) -> None:
        for raw in iter(stream.readline, b""):
            self._events.put(("line", w, (which, raw.decode(errors="replace").rstrip("\r\n"))))
        stream.close()
        if other is not None:   # the stdout pump reports the end, after every stderr line
            other.join()
            assert w.proc is not None
            self._events.put(("exit", w, w.proc.wait()))

    def _pump_socket(self, w: _Worker) -> None:
        assert w.sock is not None
        reader = w.sock.makefile("rb")
        for raw in iter(reader.readline, b""):
            msg = decode(raw)
            if msg is not None:
                self._events.put(("operator", w, msg))

    # -- the supervisor's thread -------------------------------------------------------
    def _say(self, w: _Worker, text: str) -> None:
        self.out(f"[{w.rig.name:<{self._width}}] {text}")

    def _forward_signals(self) -> None:
        if self.interrupts.count <= self._forwarded:
            return
        self._forwarded = self.interrupts.count
        sig = self.interrupts.last_signal or signal.SIGINT
        if self._forwarded == 1:
            self.out(f"tsa-bench lab: {'Ctrl-C' if sig == signal.SIGINT else 'SIGTERM'}: stopping every rig "
                     "(STOP, files closed \"aborted\")")
        for w in self.workers:
            if w.proc is not None and w.exit_code is None:
                try:
                    os.kill(w.proc.pid, sig)
                except ProcessLookupError:
                    pass

    def _reply(self, w: _Worker, message: dict[str, Any]) -> None:
        try:
            if w.sock is not None:
                w.sock.sendall(encode(message))
        except OSError:
            pass   # the rig is gone; its end is reported by its exit

    def _operator(self, w: _Worker, msg: dict[str, Any]) -> None:
        op, text = msg.get("op"), str(msg.get("text", ""))
        if op == "tell":
            for line in text.splitlines() or [""]:
                self._say(w, line)
            return
        if self.interrupts.requested:
            self._reply(w, {"abort": True})
            return
        tag = f"[{w.rig.name}]"
        if op == "answer":
            load = msg.get("load_g")
            shown = f" (load now {load:g} g)" if isinstance(load, (int, float)) else ""
            prompt = f"\n>>> {tag} {text}{shown}\n    Press Enter when done (Ctrl-C stops every rig) "
        elif op == "confirm":
            prompt = (f"\n>>> {tag} {text} [y/N]\n    Enter alone = no: {msg.get('if_no') or 'the rig does not go on'}."
                      " (Ctrl-C stops every rig) ")
        else:
            prompt = f"\n>>> {tag} {text} "
        try:
            with self.interrupts.immediate():
                typed = self.ask(prompt)
        except KeyboardInterrupt:
            self.out("")
            self._reply(w, {"abort": True})
            return
        if typed is None:
            self._reply(w, {"absent": "nobody can answer: the lab's terminal input is closed (a real rig's "
                                      "prompts need a person at the terminal)"})
        elif op == "confirm":
            self._reply(w, {"reply": "yes" if typed.strip().lower() in YES else "no"})
        else:
            self._reply(w, {"reply": "done" if op == "answer" else typed})

    def _handle(self, kind: str, w: _Worker, arg: Any) -> None:
        if kind == "line":
            which, text = arg
            self._say(w, text)
            if which == "err" and text.startswith(("error:", "run failed", "run aborted")):
                w.last_error = text
        elif kind == "operator":
            self._operator(w, arg)
        elif kind == "exit":
            w.exit_code = arg
            if w.sock is not None:
                w.sock.close()
            how = f"killed by signal {-arg}" if arg < 0 else f"exit {arg}"
            self._say(w, f"-- finished ({how})")

    def run(self) -> list[RigResult]:
        """Start every rig, serve them until all have ended, and say how each ended."""
        installed = self.interrupts.install()
        try:
            for w in self.workers:
                if self.interrupts.requested:
                    break
                self._start(w)
                if w.proc is not None:
                    self._say(w, f"started: {w.rig.plan_name} on {w.rig.port or w.rig.backend} -> {w.path}")
            running = [w for w in self.workers if w.proc is not None]
            while any(w.exit_code is None for w in running):
                self._forward_signals()
                try:
                    kind, w, arg = self._events.get(timeout=POLL_S)
                except queue.Empty:
                    continue
                self._handle(kind, w, arg)
            while not self._events.empty():
                self._handle(*self._events.get())
        finally:
            if installed:
                self.interrupts.restore()
        return [self._result(w) for w in self.workers]

    def _result(self, w: _Worker) -> RigResult:
        from tsa_bench.catalogue.runfiles import file_facts

        if w.proc is None:
            return RigResult(w.rig.name, w.path, None, "not started", reason=w.last_error or "stopped before it began")
        if not w.path.exists():
            return RigResult(w.rig.name, w.path, w.exit_code, "no file", reason=w.last_error)
        try:
            f = file_facts(w.path, with_hash=False)
        except Exception as exc:   # a damaged file is reported, not raised
            return RigResult(w.rig.name, w.path, w.exit_code, "?", reason=f"unreadable: {exc}")
        return RigResult(w.rig.name, w.path, w.exit_code, f["status"], f["samples"], f["samples_lost"],
                         f["device_time_s"], f["reason"])

    @property
    def interrupted(self) -> bool:
        return self.interrupts.requested
