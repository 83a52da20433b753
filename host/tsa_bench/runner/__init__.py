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
    "AutoOperator": "operator", "ConsoleOperator": "operator", "Operator": "operator",
}

__all__ = list(_WHERE)

if TYPE_CHECKING:
    from tsa_bench.runner.checks import PlanRejected, check_plan_against_device
    from tsa_bench.runner.engine import Runner
    from tsa_bench.runner.operator import AutoOperator, ConsoleOperator, Operator


def __getattr__(name: str) -> Any:
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module 'tsa_bench.runner' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"tsa_bench.runner.{where}"), name)
    globals()[name] = value
    return value
