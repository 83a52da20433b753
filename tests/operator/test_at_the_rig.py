"""The operator's side of the rig, end to end: the real `tsa-bench` in a pseudo-terminal
of 80x24 or 200x50, a scripted person typing at it, against a rehearsal rig that passes
for hardware (`sim-serve --as-hardware`, and the firmware core built natively with
`--as-hardware`): nobody answers for the operator. Asserted: what the screen shows (the
question whole, `[y/N]`, no traceback) and what the run files and bench files hold.
Issue 35."""

from __future__ import annotations

import os
import re
import signal
import threading
from pathlib import Path

import numpy as np
import pytest

from tests.operator.terminal import ROOT, Terminal, make_rig
from tsa_bench.bench import load_bench
from tsa_bench.store import read_run

PROMPT = "Hang 350 g [check the clamp] then wait (about 5 s)"
PROTOCOL = f"""name: at-the-rig
load_g: 200
sampling_period_s: 0.05
defaults: {{rate_turns_per_s: 3, accel_turns_per_s2: 30}}
steps:
  - move_to: {{turns: 4}}
  - hold: {{duration_s: 3}}
  - prompt: {{text: "{PROMPT}", load_g: 350}}
  - hold: {{duration_s: 5}}
  - move_to: {{turns: 0}}
"""
LONG = """name: long-hold
load_g: 200
sampling_period_s: 0.05
defaults: {rate_turns_per_s: 3, accel_turns_per_s2: 30}
steps:
  - move_to: {turns: 2}
  - hold: {duration_s: 10}
  - prompt: {text: "Look at the clamp (then Enter)"}
  - hold: {duration_s: 10}
  - move_to: {turns: 0}
"""
POSITION_Q = "Is the TSA untwisted now (strings hanging straight, twist zero)? [y/N]"


def shows(screen: str, text: str) -> bool:
    """``text`` on the screen whole, wherever the terminal wrapped it."""
    return "".join(text.split()) in "".join(screen.split())


def _rig_args(rig) -> list[str]:
    return ["--bench", "arduino-mega.yaml", "--port", rig.path]


@pytest.fixture
def rig(request):
    kind, options = request.param if isinstance(request.param, tuple) else (request.param, {})
    r = make_rig(kind, **options)
    yield r
    r.close()


def _protocol(tmp_path: Path, text: str, name: str) -> Path:
    p = tmp_path / f"{name}.yaml"
    p.write_text(text)
    return p


def _ask_position_and_say_yes(t: Terminal) -> None:
    screen = t.wait_for("(Ctrl-C aborts)")   # the whole question, its last line too
    assert shows(screen, POSITION_Q) and shows(screen, "Enter alone = no: the run stops before anything moves")
    assert "█" not in screen and "░" not in screen     # the progress line is off the screen while asking
    t.type("y\r")


@pytest.mark.parametrize("rig, size", [("sim-serve", (80, 24)), ("native", (200, 50))], indirect=["rig"])
def test_first_power_up_run_zero_check_and_calibrate(rig, size, tmp_path):
    cols, rows = size
    # check on a rig fresh from power-up: the unknown position is a finding, not "ok"
    t = Terminal(["check", "--seconds", "0.5", *_rig_args(rig)], cols, rows, tmp_path)
    assert t.finish() == 0
    out = t.screen_text()
    assert shows(out, "twist unknown (no twist zero: tsa-bench zero)") and "check: ok" not in out
    assert shows(out, "check: position unknown") and "Traceback" not in t.output()

    # a run: the position question, then a protocol prompt with brackets and parentheses
    proto = _protocol(tmp_path, PROTOCOL, "at-the-rig")
    run_file = tmp_path / "first.h5"
    t = Terminal(["run", str(proto), *_rig_args(rig), "--output", str(run_file)], cols, rows, tmp_path)
    _ask_position_and_say_yes(t)
    screen = t.wait_for("Press Enter when done")
    assert shows(screen, f">>> {PROMPT} (load now 350 g)")          # whole: no markup read into it
    assert PROMPT.encode() in t.raw and b"[y/N]" in t.raw
    assert "█" not in screen.split(">>> Hang")[-1]                    # nothing drawn over the question
    rig.hang(350)                                                     # the person hangs the mass...
    t.type("\r")                                                      # ...and says so
    assert t.finish() == 0, t.screen_text()
    run = read_run(run_file)
    assert run.exit_status == "success" and run.attrs["backend"] == "serial"
    kinds = [k.decode() if isinstance(k, bytes) else k for k in run.events["kind"]]
    details = [d.decode() if isinstance(d, bytes) else d for d in run.events["detail"]]
    assert "position_set" in kinds and PROMPT in details
    s, segs = run.samples, run.segments
    before = (s["t"] > segs["t_start"][1]) & (s["t"] < segs["t_end"][1])     # the hold before the prompt
    after = (s["t"] > segs["t_start"][3]) & (s["t"] < segs["t_end"][3])      # the hold after it
    assert before.sum() > 20 and after.sum() > 20
    # the load the person hung changed what the rig measured (it takes no load from the host)
    assert abs(np.mean(s["length"][after]) - np.mean(s["length"][before])) > 0.02

    # zero: asks, [y/N] shown, yes sets the position
    t = Terminal(["zero", *_rig_args(rig)], cols, rows, tmp_path)
    screen = t.wait_for("(Ctrl-C aborts)")   # the whole question, its last line too
    assert shows(screen, "Is the TSA hanging untwisted (twist zero) now? Later twist limits count from here. [y/N]")
    t.type("y\r")
    assert t.finish() == 0
    assert shows(t.screen_text(), "position set 0 turns (0 steps)")

    t = Terminal(["check", "--seconds", "0.5", *_rig_args(rig)], cols, rows, tmp_path)
    assert t.finish() == 0
    assert shows(t.screen_text(), "twist 0 turns") and "position unknown" not in t.screen_text()

    # calibrate position with typed ruler readings -> a new bench file
    t = Terminal(["calibrate", "position", "--at-turns", "0,10,20", "--seconds", "0.3", *_rig_args(rig),
                  "--out", str(tmp_path / "cal.yaml")], cols, rows, tmp_path)
    for i, reading in enumerate(("300", "290", "280")):
        t.wait_raw("ruler length now (mm):", i + 1)
        t.type(f"{reading}\r")
        t.wait_for(f"= {reading} mm")
    assert t.finish() == 0, t.screen_text()
    cal = load_bench(tmp_path / "cal.yaml")
    assert cal.position.mm_per_count != load_bench(ROOT / "configs" / "bench" / "arduino-mega.yaml").position.mm_per_count


@pytest.mark.parametrize("rig, size", [("sim-serve", (200, 50)), ("native", (80, 24))], indirect=["rig"])
def test_enter_alone_at_the_position_question_stops_before_anything_moves(rig, size, tmp_path):
    proto = _protocol(tmp_path, PROTOCOL, "at-the-rig")
    run_file = tmp_path / "enter.h5"
    t = Terminal(["run", str(proto), *_rig_args(rig), "--output", str(run_file)], *size, tmp_path)
    screen = t.wait_for("(Ctrl-C aborts)")   # the whole question, its last line too
    assert shows(screen, POSITION_Q)
    assert shows(screen, "Enter alone = no: the run stops before anything moves")   # Enter says what it does
    t.type("\r")
    assert t.finish() == 1
    out = t.screen_text()
    assert shows(out, "no segment was done: fix the cause above and run it again") and "--resume" not in out
    assert shows(out, "nothing moved")
    run = read_run(run_file)
    assert run.exit_status == "failed" and len(run.samples["t"]) == 0


@pytest.mark.parametrize("rig", ["sim-serve", "native"], indirect=True)
def test_a_thesis_protocol_with_its_load_prompts_answered_by_typing(rig, tmp_path):
    proto = ROOT / "configs" / "protocols" / "stiffness-3ply.yaml"
    prompts = re.findall(r'prompt: \{text: "([^"]+)", load_g: (\d+)\}', proto.read_text())
    assert len(prompts) == 9
    run_file = tmp_path / "stiffness.h5"
    t = Terminal(["run", str(proto), *_rig_args(rig), "--output", str(run_file)], 80, 24, tmp_path)
    _ask_position_and_say_yes(t)
    for i, (text, grams) in enumerate(prompts):
        question = f">>> {text} (load now {grams} g)"
        t.wait_raw(question, sum(q == (text, grams) for q in prompts[:i + 1]))   # this one, not an earlier twin
        t.wait_raw("Press Enter when done (Ctrl-C aborts the run)", i + 1)   # its prompt line may come in a later read
        assert shows(t.screen_text(), f"{question} Press Enter when done (Ctrl-C aborts the run)")
        rig.hang(float(grams))
        t.type("\r")
    assert t.finish() == 0, t.screen_text()
    run = read_run(run_file)
    assert run.exit_status == "success"
    loads = [float(d.decode().split()[2]) if isinstance(d, bytes) else float(d.split()[2])
             for k, d in zip(run.events["kind"], run.events["detail"]) if (k.decode() if isinstance(k, bytes) else k) == "load"]
    assert loads == [float(g) for _, g in prompts]


@pytest.mark.parametrize("rig", [("sim-serve", {"reset_on_open": False}), ("native", {"reset_on_open": False})],
                         indirect=True)
def test_ctrl_c_then_the_latched_fault_is_shown_and_cleared_and_the_run_resumed(rig, tmp_path):
    """A Mega wired not to reset on open: Ctrl-C leaves sampling on, the watchdog trips;
    `check` shows the fault and clears it; `run --resume` continues."""
    proto = _protocol(tmp_path, LONG, "long-hold")
    run_file = tmp_path / "long.h5"
    t = Terminal(["run", str(proto), *_rig_args(rig), "--output", str(run_file)], 80, 24, tmp_path)
    _ask_position_and_say_yes(t)
    t.wait_for(">>> Look at the clamp (then Enter)")   # moved and held, the device sampling: mid-run
    t.interrupt()
    assert t.finish() == 130
    assert shows(t.screen_text(), f"to continue it later: tsa-bench run --resume {run_file}")
    rig.wait_fault()

    t = Terminal(["check", "--seconds", "0.3", *_rig_args(rig)], 80, 24, tmp_path)
    code = t.finish()
    out = t.output()                    # all it printed (more than a 24-line screen holds)
    assert shows(out, "fault device fault watchdog latched") and shows(out, "Clearing it now (CLEAR_QUEUE)")
    assert shows(out, "the next `tsa-bench check`, `zero` or `run` clears it")
    assert shows(out, "fault none (watchdog cleared above)") and code == 0, out

    resumed = tmp_path / "resumed.h5"
    t = Terminal(["run", "--resume", str(run_file), *_rig_args(rig), "--output", str(resumed)], 80, 24, tmp_path)
    screen = t.wait_for("Continue? [y/N]")
    assert shows(screen, "The motor will move to 2 turns from where the device is now")
    t.type("y\r")
    # the device released its motor if the fault outlasted 10 s of its time: then it asks the twist zero too
    if t.wait_raw_any([POSITION_Q, ">>> Look at the clamp"]) == POSITION_Q:
        t.type("y\r")
    t.wait_raw(">>> Look at the clamp (then Enter)")    # the resumed run starts at the interrupted prompt
    t.type("\r")
    code = t.finish()
    assert code == 0, t.screen_text()
    run = read_run(resumed)
    assert run.exit_status == "success" and list(run.segments["index"]) == [2, 3, 4]


@pytest.mark.parametrize("rig", ["sim-serve", "native"], indirect=True)
def test_a_stall_during_calibrate_keeps_the_readings(rig, tmp_path):
    """The rig freezes for 4 s (SIGSTOP) after two ruler readings: one error line, no
    traceback, the two points kept as a --points command that re-fits them; the same
    stall during `check`: one error line."""
    zero = Terminal(["zero", "--yes", *_rig_args(rig)], 80, 24, tmp_path)
    assert zero.finish() == 0
    t = Terminal(["calibrate", "position", "--at-turns", "0,10,20", "--seconds", "0.3", *_rig_args(rig)],
                 80, 24, tmp_path)
    for i, reading in enumerate(("300", "290")):
        t.wait_raw("ruler length now (mm):", i + 1)
        if i == 1:
            os.kill(rig.pid, signal.SIGSTOP)
            threading.Timer(4.0, os.kill, (rig.pid, signal.SIGCONT)).start()
        t.type(f"{reading}\r")
    assert t.finish() == 1
    out = t.output()
    assert "Traceback" not in out
    screen = t.screen_text()
    assert shows(screen, "the 2 point(s) measured so far are kept")
    command = re.search(r"tsa-bench (calibrate position --bench \S+ --points \S+)", "".join(screen.split("\n")))
    saved = list(tmp_path.glob("*-points.txt"))
    assert len(saved) == 1 and "--points" in saved[0].read_text()
    points = re.search(r"--points (\S+)", saved[0].read_text()).group(1)
    assert len(points.split(",")) == 2 and points.split(",")[0].endswith("=300")
    refit = Terminal(["calibrate", "position", "--bench", "arduino-mega.yaml", "--points", points,
                      "--out", str(tmp_path / "refit.yaml")], 80, 24, tmp_path)
    assert refit.finish() == 0, refit.screen_text()
    assert (tmp_path / "refit.yaml").exists() and command is not None

    # the same stall while `check` reads the sensors: one line, exit 1
    t = Terminal(["check", "--seconds", "6", *_rig_args(rig)], 80, 24, tmp_path)
    t.wait_for("limits ")
    os.kill(rig.pid, signal.SIGSTOP)
    threading.Timer(4.0, os.kill, (rig.pid, signal.SIGCONT)).start()
    assert t.finish() == 1
    assert "Traceback" not in t.output()
    errors = [line for line in t.screen_text().splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "no ACK" in errors[0], t.screen_text()
