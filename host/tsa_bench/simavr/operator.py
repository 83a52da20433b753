"""The operator of the firmware-in-the-loop bench: answers prompts by changing the
plant's load, as a person hanging weights would.

Contract: :class:`PlantOperator` satisfies :class:`tsa_bench.operator.OperatorChannel`.
The real firmware knows nothing of loads (SIM_SET_LOAD is unknown to it), so the load
reaches the plant on the host side: at once for the plan's initial load
(:meth:`apply_initial`), and when a prompt declares one.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

from tsa_bench.operator import AutoOperator


class LoadSink(Protocol):
    def set_load_g(self, load_g: float) -> None: ...


class PlantOperator(AutoOperator):
    """Answers every prompt at once; a declared load goes to the plant (g)."""

    def __init__(self, sink: LoadSink, say: Callable[[str], None] | None = None) -> None:
        super().__init__(say)
        self._sink = sink

    def apply_initial(self, load_g: float | None) -> None:
        if load_g is not None and math.isfinite(load_g):
            self._sink.set_load_g(load_g)

    def answer(self, text: str, load_g: float | None) -> None:
        super().answer(text, load_g)
        if load_g is not None:
            self._sink.set_load_g(load_g)
