"""Operator prompts ("hang 200 g"): who answers them.

Contract: ``answer(text, load_g)`` returns once the operator has done what the prompt
asks; ``confirm(question)`` returns the operator's yes or no; raising KeyboardInterrupt
aborts the run. The simulated bench answers at once (the runner then changes the
simulated load) and says yes; a real bench asks a person.
"""

from __future__ import annotations

from typing import Callable, Protocol


class Operator(Protocol):
    def answer(self, text: str, load_g: float | None) -> None: ...

    def confirm(self, question: str) -> bool: ...


class AutoOperator:
    """Answers every prompt immediately (simulated bench, tests)."""

    def __init__(self) -> None:
        self.prompts: list[str] = []

    def answer(self, text: str, load_g: float | None) -> None:
        self.prompts.append(text)

    def confirm(self, question: str) -> bool:
        """Yes: a simulated rig is whatever the question assumes (its plant starts untwisted)."""
        self.prompts.append(question)
        return True


class ConsoleOperator:
    """Asks a person on the terminal and waits for Enter."""

    def __init__(self, ask: Callable[[str], str] = input) -> None:
        self._ask = ask

    def answer(self, text: str, load_g: float | None) -> None:
        load = f" (load now {load_g:g} g)" if load_g is not None else ""
        self._ask(f"\n>>> {text}{load}. Press Enter when done (Ctrl-C aborts the run) ")

    def confirm(self, question: str) -> bool:
        reply = self._ask(f"\n>>> {question} [y/N] (Ctrl-C aborts the run) ")
        return reply.strip().lower() in ("y", "yes")
