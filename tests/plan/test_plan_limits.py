"""Limits: construction checks and tighten-only merging."""

from __future__ import annotations

import pytest

from tsa_bench.benchdata import Limits
from plan_helpers import BENCH


def test_default_limits_are_unlimited() -> None:
    lim = Limits()
    assert lim.as_dict() == dict.fromkeys(Limits.field_names())


def test_tightened_with_mapping_keeps_other_fields() -> None:
    out = BENCH.tightened({"max_twist_turns": 30, "min_twist_turns": 0, "max_rate_turns_per_s": None})
    assert out.max_twist_turns == 30 and out.min_twist_turns == 0
    assert out.max_rate_turns_per_s == 5 and out.max_heater_voltage_V == 12


def test_tightened_with_limits_object() -> None:
    out = BENCH.tightened(Limits(max_heater_voltage_V=8))
    assert out.max_heater_voltage_V == 8 and out.max_twist_turns == 100


def test_tightening_unlimited_bench_accepts_anything() -> None:
    assert Limits().tightened({"max_twist_turns": 1e6}).max_twist_turns == 1e6


@pytest.mark.parametrize(
    "change",
    [{"max_twist_turns": 101}, {"min_twist_turns": -11}, {"max_heater_voltage_V": 13},
     {"max_rate_turns_per_s": 6}, {"max_accel_turns_per_s2": 101}],
)
def test_loosening_is_refused_and_named(change: dict[str, float]) -> None:
    with pytest.raises(ValueError, match="only tighten") as info:
        BENCH.tightened(change)
    assert next(iter(change)) in str(info.value)


def test_unknown_field_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown limit"):
        BENCH.tightened({"max_speed": 1})


@pytest.mark.parametrize(
    "kwargs",
    [{"max_rate_turns_per_s": 0}, {"max_accel_turns_per_s2": -1}, {"max_heater_voltage_V": -1},
     {"min_twist_turns": 5, "max_twist_turns": 1}, {"max_twist_turns": float("nan")},
     {"max_twist_turns": True}],
)
def test_invalid_limits_raise(kwargs: dict[str, float]) -> None:
    with pytest.raises(ValueError):
        Limits(**kwargs)


def test_limits_are_stored_as_floats() -> None:
    assert isinstance(Limits(max_twist_turns=3).max_twist_turns, float)
