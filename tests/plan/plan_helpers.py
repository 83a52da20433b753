"""Shared helpers for the plan tests: the reference bench limits and small YAML builders.

(A uniquely named module rather than ``conftest.py`` so test modules can import it
without clashing with other test folders' conftest files.)"""

from __future__ import annotations

from pathlib import Path

import pytest

from tsa_bench.benchdata import Limits
from tsa_bench.plan import PlanErrors, load_plan_text

PROTOCOL_DIR = Path(__file__).resolve().parents[2] / "configs" / "protocols"

#: Bench limits every shipped protocol must validate against.
BENCH = Limits(
    max_twist_turns=100,
    min_twist_turns=-10,
    max_heater_voltage_V=12,
    max_rate_turns_per_s=5,
    max_accel_turns_per_s2=100,
)

#: Three header lines; the first step therefore sits on line 4.
HEADER = "name: t\ndefaults: {rate_turns_per_s: 1, accel_turns_per_s2: 10}\nsteps:\n"


def protocol(*steps: str) -> str:
    """YAML text with ``HEADER`` and one ``  - step`` line per argument (first on line 4)."""
    return HEADER + "".join(f"  - {s}\n" for s in steps)


def errors_of(text: str, limits: Limits = BENCH, filename: str = "p.yaml") -> PlanErrors:
    """The PlanErrors that loading ``text`` raises (fails the test if it loads)."""
    with pytest.raises(PlanErrors) as info:
        load_plan_text(text, limits, filename)
    return info.value
