"""The operator channel interface, and the operator that answers by itself.

Units: loads in g.

Contract: a channel carries text whole to a person, exactly as given (a protocol's
``prompt`` text, a question holding ``[y/N]`` or brackets of its own: never read as
markup, never wrapped or cut), and returns what the person answered:

* :meth:`~OperatorChannel.tell` a notice; nothing comes back.
* :meth:`~OperatorChannel.answer` a prompt ("hang 350 g"): returns once the person
  says it is done; ``load_g`` is the load the prompt declares (None: none).
* :meth:`~OperatorChannel.confirm` a yes/no question: True only for an explicit yes.
  ``if_no`` says what a no does ("the run stops; nothing moves"), and a channel shows
  it with the question, because Enter alone answers no: no question defaults to the
  answer that fails a run without saying so.
* :meth:`~OperatorChannel.ask` a value to type (a ruler reading); "" when the person
  pressed Enter alone.

Every method may raise KeyboardInterrupt (the person aborts) or :class:`OperatorAbsent`
(nobody can answer: the terminal's input closed). A channel that shows a live display
(a progress bar) holds it while a person is asked (:class:`Pausable`), so the question
is not drawn over.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol


class OperatorAbsent(RuntimeError):
    """Nobody can answer: the message says why (the input closed, no terminal)."""


class OperatorChannel(Protocol):
    """See the module contract."""

    def tell(self, text: str) -> None: ...

    def answer(self, text: str, load_g: float | None) -> None: ...

    def confirm(self, question: str, *, if_no: str) -> bool: ...

    def ask(self, question: str) -> str: ...


class Pausable(Protocol):
    """A live display a channel holds while a person is asked."""

    def pause(self) -> None: ...

    def resume(self) -> None: ...


class AutoOperator:
    """Answers at once (simulated bench, tests): every prompt done, every question yes,
    every typed value Enter alone. :attr:`prompts` keeps what it was given, in order;
    notices also go to ``say`` when given (a person watching a simulated run)."""

    def __init__(self, say: Callable[[str], None] | None = None) -> None:
        self.prompts: list[str] = []
        self._say = say

    def tell(self, text: str) -> None:
        self.prompts.append(text)
        if self._say is not None:
            self._say(text)

    def answer(self, text: str, load_g: float | None) -> None:
        self.prompts.append(text)

    def confirm(self, question: str, *, if_no: str = "") -> bool:
        """Yes: a simulated rig is whatever the question assumes (its plant starts untwisted)."""
        self.prompts.append(question)
        return True

    def ask(self, question: str) -> str:
        self.prompts.append(question)
        return ""
