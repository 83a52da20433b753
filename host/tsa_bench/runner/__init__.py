"""Run engine: executes a plan on a bench and emits run documents (:mod:`tsa_bench.rundocs`) to consumers.

The names below are imported on first use (PEP 562), so importing one submodule
(``tsa_bench.runner.commands`` for ``validate``, ``tsa_bench.runner.interrupts``)
does not load the engine, the device client and the store with it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

#: public name -> the submodule that defines it
_WHERE = {
    "PlanRejected": "checks", "check_plan_against_device": "checks", "Runner": "engine",
    # the operator channel lives in its own room below the runner (tsa_bench.operator)
    "AutoOperator": "tsa_bench.operator.channel", "Operator": "tsa_bench.operator.channel:OperatorChannel",
    "ConsoleOperator": "tsa_bench.operator.terminal:TerminalOperator",
}

__all__ = list(_WHERE)

if TYPE_CHECKING:
    from tsa_bench.runner.checks import PlanRejected, check_plan_against_device
    from tsa_bench.runner.engine import Runner
    from tsa_bench.operator.channel import AutoOperator
    from tsa_bench.operator.channel import OperatorChannel as Operator
    from tsa_bench.operator.terminal import TerminalOperator as ConsoleOperator


def __getattr__(name: str) -> Any:
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module 'tsa_bench.runner' has no attribute {name!r}")
    module, _, attr = where.partition(":")
    module = module if "." in module else f"tsa_bench.runner.{module}"
    value = getattr(importlib.import_module(module), attr or name)
    globals()[name] = value
    return value
