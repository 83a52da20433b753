"""The person at this terminal, as an operator channel.

Contract: :class:`TerminalOperator` satisfies
:class:`~tsa_bench.operator.channel.OperatorChannel`. Text goes out as plain characters
on the output stream (standard output unless given), whole and unchanged: no markup,
no highlighting, no wrapping; a question starts on a line of its own. Every display
registered with :meth:`TerminalOperator.hold` is paused before the text goes out and
resumed after the answer (also when the person aborts), so a live progress line
neither draws over the question nor catches the typed keys. A closed input raises
:class:`~tsa_bench.operator.channel.OperatorAbsent`.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TextIO

from tsa_bench.operator.channel import OperatorAbsent, Pausable

#: What a person types for yes (case ignored, spaces around ignored).
YES = ("y", "yes")


class TerminalOperator:
    """A person at the terminal (see the module contract)."""

    def __init__(self, ask: Callable[[str], str] | None = None, out: TextIO | None = None) -> None:
        """``ask(text)`` shows ``text`` and returns the line typed without its newline (default:
        the output stream and standard input, looked up at each question, so a redirection
        made later is honoured); EOFError from it means the input closed."""
        self._ask = ask
        self._out = out
        self._displays: list[Pausable] = []

    def hold(self, display: Pausable) -> None:
        """Pause ``display`` whenever a person is asked."""
        self._displays.append(display)

    # -- the channel ---------------------------------------------------------
    def tell(self, text: str) -> None:
        with self._held():
            self._write(f"{text}\n")

    def answer(self, text: str, load_g: float | None) -> None:
        load = f" (load now {load_g:g} g)" if load_g is not None else ""
        self._line(f"\n>>> {text}{load}\n    Press Enter when done (Ctrl-C aborts the run) ")

    def confirm(self, question: str, *, if_no: str) -> bool:
        reply = self._line(f"\n>>> {question} [y/N]\n    Enter alone = no: {if_no}. (Ctrl-C aborts) ")
        return reply.strip().lower() in YES

    def ask(self, question: str) -> str:
        return self._line(question)

    # -- plumbing ------------------------------------------------------------
    @contextmanager
    def _held(self) -> Iterator[None]:
        paused = []
        try:
            for d in self._displays:
                d.pause()
                paused.append(d)
            yield
        finally:
            for d in reversed(paused):
                d.resume()

    def _stream(self) -> TextIO:
        return self._out if self._out is not None else sys.stdout

    def _write(self, text: str) -> None:
        out = self._stream()
        out.write(text)
        out.flush()

    def _line(self, text: str) -> str:
        with self._held():
            try:
                if self._ask is not None:
                    return self._ask(text)
                self._write(text)
                line = sys.stdin.readline()
            except EOFError:
                line = ""
            if not line:   # readline gives "\n" for Enter alone, "" only at the end of the input
                raise OperatorAbsent("nobody can answer: the terminal's input is closed (a question needs a "
                                     "person at the terminal; a simulated bench answers by itself)")
            return line.rstrip("\r\n")
