"""An operator at a terminal, scripted: the real `tsa-bench` in a pseudo-terminal of a
given size (pexpect), its screen as a person sees it (pyte), and the rehearsal rigs it
talks to (`tsa-bench sim-serve --as-hardware`, the native firmware passing for a Mega).

Everything waits on a condition (text on the screen, a line from the rig, the process
ending) with a generous deadline; nothing waits for a fixed time.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pexpect
import pyte

ROOT = Path(__file__).resolve().parents[2]
DEADLINE_S = 120.0


def cli_env() -> dict[str, str]:
    """The environment of a command run as a person would: this checkout's package first."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "host"), str(ROOT)])
    env["TERM"] = "xterm-256color"
    for key in ("TTY_COMPATIBLE", "FORCE_COLOR", "NO_COLOR", "COLUMNS", "LINES"):
        env.pop(key, None)
    return env


class Terminal:
    """One `tsa-bench` command in a pty of ``cols`` x ``rows``; :meth:`screen_text` is what shows."""

    def __init__(self, args: list[str], cols: int, rows: int, cwd: Path) -> None:
        self.cols, self.rows = cols, rows
        self.child = pexpect.spawn(sys.executable, ["-m", "tsa_bench.cli", *args], dimensions=(rows, cols),
                                   env=cli_env(), cwd=str(cwd), encoding=None, timeout=DEADLINE_S)
        self.screen = pyte.Screen(cols, rows)
        self.stream = pyte.ByteStream(self.screen)
        self.raw = bytearray()

    # -- reading -------------------------------------------------------------
    def _pump(self, timeout_s: float) -> bool:
        """Feed what the command printed into the screen; False at its end."""
        try:
            data = self.child.read_nonblocking(65536, timeout=timeout_s)
        except pexpect.TIMEOUT:
            return True
        except pexpect.EOF:
            return False
        self.raw += data
        self.stream.feed(data)
        return True

    def screen_text(self) -> str:
        """The screen now, a line that fills the width joined to the next (a wrapped line)."""
        out = []
        for line in self.screen.display:
            out.append(line.rstrip())
            out.append("" if len(line.rstrip()) == self.cols else "\n")
        return "".join(out)

    def wait_for(self, text: str, deadline_s: float = DEADLINE_S) -> str:
        """Until ``text`` shows on the screen (returns the screen); fails at the deadline or the end."""
        end = time.monotonic() + deadline_s
        while time.monotonic() < end:
            shown = self.screen_text()
            if text in shown:
                return shown
            if not self._pump(0.1):
                shown = self.screen_text()
                if text in shown:
                    return shown
                raise AssertionError(f"the command ended before {text!r} showed; screen:\n{shown}\n"
                                     f"output:\n{self.output()[-3000:]}")
        raise AssertionError(f"{text!r} did not show within {deadline_s} s; screen:\n{self.screen_text()}")

    def wait_raw(self, text: str, count: int = 1, deadline_s: float = DEADLINE_S) -> None:
        """Until the command has printed ``text`` ``count`` times (its own bytes, before the screen)."""
        end, want = time.monotonic() + deadline_s, text.encode()
        while self.raw.count(want) < count:
            if time.monotonic() > end or not self._pump(0.1):
                if self.raw.count(want) >= count:
                    return
                raise AssertionError(f"{text!r} not printed {count} times; screen:\n{self.screen_text()}")

    def wait_raw_any(self, texts: list[str], deadline_s: float = DEADLINE_S) -> str:
        """Until the command prints one of ``texts`` (from now on); which one."""
        start, end = len(self.raw), time.monotonic() + deadline_s
        while True:
            for text in texts:
                if text.encode() in self.raw[start:]:
                    return text
            if time.monotonic() > end or not self._pump(0.1):
                raise AssertionError(f"none of {texts} printed; screen:\n{self.screen_text()}")

    def output(self) -> str:
        """Everything printed, control sequences removed as the screen applied them (approximate)."""
        return self.raw.decode(errors="replace")

    # -- typing --------------------------------------------------------------
    def type(self, text: str) -> None:
        self.child.send(text.encode())

    def interrupt(self) -> None:
        self.child.sendintr()

    def finish(self, deadline_s: float = DEADLINE_S) -> int:
        """Read to the end; the exit code (128 + n for a signal)."""
        end = time.monotonic() + deadline_s
        while self._pump(0.2):
            if time.monotonic() > end:
                self.child.kill(signal.SIGKILL)
                raise AssertionError(f"the command did not end within {deadline_s} s; screen:\n"
                                     f"{self.screen_text()}")
        self.child.close()
        return self.child.exitstatus if self.child.exitstatus is not None else 128 + self.child.signalstatus


class SimRig:
    """`tsa-bench sim-serve --as-hardware`: the rehearsal rig (a person types loads at it)."""

    name = "sim-serve"

    def __init__(self, *, reset_on_open: bool = True) -> None:
        args = [sys.executable, "-m", "tsa_bench.cli", "sim-serve", "--as-hardware"]
        if not reset_on_open:
            args.append("--no-reset-on-open")
        self.proc = subprocess.Popen(args, cwd=ROOT, env=cli_env(), stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, bufsize=1)
        self.path = self.proc.stdout.readline().strip()
        self.lines: list[str] = []
        self._changed = threading.Condition()
        threading.Thread(target=self._read, daemon=True).start()
        assert self.path.startswith("/dev/"), self.path

    def _read(self) -> None:
        for line in self.proc.stderr:
            with self._changed:
                self.lines.append(line.rstrip())
                self._changed.notify_all()

    def said(self, text: str, deadline_s: float = DEADLINE_S, since: int = 0) -> int:
        """Until the rig printed a line holding ``text`` (index ``since`` on); the line's index."""
        end = time.monotonic() + deadline_s
        with self._changed:
            while True:
                for i in range(since, len(self.lines)):
                    if text in self.lines[i]:
                        return i
                left = end - time.monotonic()
                if left <= 0:
                    raise AssertionError(f"the rig did not say {text!r}; it said {self.lines[-10:]}")
                self._changed.wait(left)

    def hang(self, grams: float) -> None:
        self.proc.stdin.write(f"{grams:g}\n")
        self.proc.stdin.flush()
        self.said(f"rig: {grams:g} g hanging now")

    def wait_fault(self, deadline_s: float = DEADLINE_S) -> None:
        self.said("rig: fault watchdog latched", deadline_s)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def close(self) -> None:
        self.proc.terminate()
        self.proc.wait(10)


class NativeRig:
    """The firmware core built natively, passing for a Mega behind a pty."""

    name = "native"

    def __init__(self, *, reset_on_open: bool = True) -> None:
        from tests.rig.native_pty import NativeFirmwarePty

        built = subprocess.run(["make", "-C", "firmware", "native"], cwd=ROOT, capture_output=True, text=True)
        assert built.returncode == 0, built.stdout + built.stderr
        self.fw = NativeFirmwarePty(ROOT / "firmware" / "build" / "tsa_bench_native", "--virtual",
                                    as_hardware=True, reset_on_open=reset_on_open)
        self.path = self.fw.path

    def hang(self, grams: float) -> None:
        self.fw.hang(grams)

    def wait_fault(self, deadline_s: float = DEADLINE_S) -> None:
        end = time.monotonic() + deadline_s
        while 1 not in self.fw.faults:   # fault watchdog
            if time.monotonic() > end:
                raise AssertionError(f"no watchdog fault; faults seen {self.fw.faults}")
            time.sleep(0.05)

    @property
    def pid(self) -> int:
        return self.fw.proc.pid

    def close(self) -> None:
        self.fw.close()


def make_rig(kind: str, **options):
    return SimRig(**options) if kind == "sim-serve" else NativeRig(**options)
