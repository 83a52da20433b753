"""The operator channel: text whole, displays held while a person is asked, no answer
possible said so; the progress line as a display the channel holds; the rehearsal
device's identity and reset. Issue 35."""

from __future__ import annotations

import io
import sys

import pytest

from tsa_bench.bench import load_bench
from tsa_bench.operator import AutoOperator, OperatorAbsent
from tsa_bench.operator.terminal import TerminalOperator
from tsa_bench.protocol import msg

TEXT = "Hang 350 g [check the clamp] then wait (about 5 s) [bold]x[/bold]"


class Display:
    def __init__(self, log: list[str]) -> None:
        self.log = log

    def pause(self) -> None:
        self.log.append("pause")

    def resume(self) -> None:
        self.log.append("resume")


def test_text_goes_out_whole_and_the_display_is_held_around_the_answer(monkeypatch):
    out, log = io.StringIO(), []
    monkeypatch.setattr(sys, "stdin", io.StringIO("y\n\n42.5\n"))
    person = TerminalOperator(out=out)
    person.hold(Display(log))
    assert person.confirm(f"{TEXT}?", if_no="the run stops") is True
    person.answer(TEXT, 350)
    assert person.ask("ruler length now (mm): ") == "42.5"
    shown = out.getvalue()
    assert f">>> {TEXT}? [y/N]\n    Enter alone = no: the run stops." in shown
    assert f">>> {TEXT} (load now 350 g)\n    Press Enter when done" in shown
    assert log == ["pause", "resume"] * 3


def test_enter_alone_is_no_and_a_closed_input_is_no_answer(monkeypatch):
    out = io.StringIO()
    monkeypatch.setattr(sys, "stdin", io.StringIO("\n"))
    person = TerminalOperator(out=out)
    assert person.confirm("Untwisted?", if_no="nothing moves") is False
    with pytest.raises(OperatorAbsent, match="input is closed"):
        person.confirm("Untwisted?", if_no="nothing moves")


def test_the_display_comes_back_when_the_person_aborts():
    log: list[str] = []

    def ctrl_c(text: str) -> str:
        raise KeyboardInterrupt

    person = TerminalOperator(ask=ctrl_c)
    person.hold(Display(log))
    with pytest.raises(KeyboardInterrupt):
        person.answer("Hang 200 g", 200)
    assert log == ["pause", "resume"]


def test_the_automatic_operator_answers_yes_and_passes_notices_on():
    said: list[str] = []
    auto = AutoOperator(say=said.append)
    assert auto.confirm("Untwisted?", if_no="x") is True and auto.ask("reading: ") == ""
    auto.tell("a fault was latched")
    assert said == ["a fault was latched"] and auto.prompts[-1] == "a fault was latched"


def test_the_progress_line_pauses_and_prints_what_passes_through_it_whole():
    """While the line shows, stdout goes through rich; it must not read [tags] in it."""
    from rich.console import Console

    from tsa_bench.console.progress import ProgressDisplay
    from tsa_bench.rundocs import RunStart

    term = io.StringIO()
    display = ProgressDisplay(Console(file=term, force_terminal=True, width=200, markup=False, highlight=False))
    display.on_start(RunStart(plan_name="p", protocol_text="", protocol_path=None, bench_text="", bench_path=None,
                              backend="serial", port="x", firmware="0", identity={}, n_segments=3,
                              estimated_duration_s=10.0))
    try:
        assert display._live.is_started
        print(TEXT, end="")          # an input() prompt: no newline, flushed
        sys.stdout.flush()
        display.pause()
        assert not display._live.is_started
        display.resume()
        assert display._live.is_started
    finally:
        display._live.stop()
    assert TEXT in term.getvalue()


def test_the_default_progress_console_reads_no_markup(monkeypatch):
    from tsa_bench.console.progress import ProgressDisplay

    display = ProgressDisplay()
    assert display.console._markup is False


def test_a_rehearsal_device_passes_for_hardware_and_resets_like_a_mega():
    from tsa_bench.protocol import MessageDecoder, encode
    from tsa_bench.sim.device import SimDevice

    bench = load_bench(None)
    dev = SimDevice(bench, simulated=False)
    assert dev.identity.flags & msg.DeviceFlags.SIMULATED == 0
    dev.receive(encode(msg.SimSetLoad(100_000), 7))
    acks = [f.message for f in MessageDecoder().feed(dev.take_output()) if isinstance(f.message, msg.Ack)]
    assert acks[-1].status == msg.Status.UNKNOWN_MESSAGE
    assert SimDevice(bench).identity.flags & msg.DeviceFlags.SIMULATED
    dev.receive(encode(msg.SetPosition(3200), 8))
    dev.take_output()
    after = dev.after_reset()
    boot = [f.message for f in MessageDecoder().feed(after.take_output())]
    assert boot[-1].reason == msg.BootReason.EXTERNAL_RESET
    assert after.position_known and after.executor.position_steps == 3200 and after.plant is dev.plant
    assert not after.simulated
    fresh = SimDevice(bench, simulated=False)
    assert not fresh.after_reset().position_known        # never declared: unknown after the reset too
