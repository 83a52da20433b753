"""The operator channel of a Bluesky plan: nobody is at a terminal, so a question is refused.

Contract: :class:`OperatorRefusal` is the operator a protocol flyer on a real rig gets
when no other is given. It answers no prompt and no question: each raises
:class:`~tsa_bench.operator.channel.OperatorAbsent` whose message holds the prompt's text whole and says how to run
it instead, and the runner then ends the protocol "failed" after STOP (motor halted,
heater off). A plan that needs a person answers through its own operator object (any
object with ``answer(text, load_g)`` and ``confirm(question)``), passed to the flyer.
"""

from __future__ import annotations

from tsa_bench.operator.channel import OperatorAbsent


class OperatorRefusal:
    """Refuses every prompt and question (see the module contract)."""

    HOW = ("a Bluesky plan asks nobody at a terminal: run this protocol with `tsa-bench run`, or give the flyer "
           "an operator that answers (ProtocolFlyer(rig, path, operator=...))")

    def tell(self, text: str) -> None:
        """A notice needs no answer: nothing to refuse."""

    def answer(self, text: str, load_g: float | None) -> None:
        load = f" (load {load_g:g} g)" if load_g is not None else ""
        raise OperatorAbsent(f"the protocol asks the operator: {text!r}{load}; {self.HOW}")

    def confirm(self, question: str, *, if_no: str = "") -> bool:
        raise OperatorAbsent(f"the protocol asks the operator: {question!r}; {self.HOW}")

    def ask(self, question: str) -> str:
        raise OperatorAbsent(f"the protocol asks the operator: {question!r}; {self.HOW}")
