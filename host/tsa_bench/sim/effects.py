"""Named plant effects: corrections applied, in order, to the quasi-static reading.

Units: time in s, twist in motor turns, heater voltage in V, load in g, length in mm,
resistance in ohm.

Contract: an effect is a small stateful object with ``apply(inputs, reading) ->
reading``; the plant calls it once per sample with nondecreasing ``inputs.t_s``, so an
effect may keep state between calls (thermal lag, hysteresis operators, creep, transient
decay). Effects are built by name from the bench file's ``plant.effects`` list through
:data:`EFFECTS`; each factory receives its parameter mapping (without ``name``) and its
own seeded ``random.Random``, and must raise ``ValueError`` naming any bad key. Adding
an effect means writing a class and registering a factory with :func:`register_effect`.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Mapping
from typing import Any, NamedTuple, Protocol

from tsa_bench.sim.readings import PlantReading


class PlantInputs(NamedTuple):
    """What the plant is driven with at one sample."""

    t_s: float
    turns: float
    heater_voltage_V: float
    motor_moving: bool
    load_g: float


class PlantEffect(Protocol):
    """One named correction to the plant's reading."""

    def apply(self, inputs: PlantInputs, reading: PlantReading) -> PlantReading: ...


EffectFactory = Callable[[Mapping[str, Any], random.Random], PlantEffect]

#: Effect name -> factory(params, rng). Populated with :func:`register_effect`.
EFFECTS: dict[str, EffectFactory] = {}


def register_effect(name: str) -> Callable[[EffectFactory], EffectFactory]:
    """Decorator registering a factory under ``name`` (names are unique)."""
    def deco(factory: EffectFactory) -> EffectFactory:
        if name in EFFECTS:
            raise ValueError(f"plant effect '{name}' is already registered")
        EFFECTS[name] = factory
        return factory
    return deco


def number_param(params: Mapping[str, Any], key: str, where: str, default: float | None = None,
                 minimum: float | None = None) -> float:
    """Read a numeric parameter; raise ValueError naming ``where`` and ``key``."""
    if key not in params:
        if default is None:
            raise ValueError(f"{where}: missing required key '{key}'")
        return default
    value = params[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value:
        raise ValueError(f"{where}: '{key}' must be a number, got {value!r}")
    if minimum is not None and value < minimum:
        raise ValueError(f"{where}: '{key}' must be >= {minimum}, got {value}")
    return float(value)


def check_keys(params: Mapping[str, Any], allowed: tuple[str, ...], where: str) -> None:
    """Refuse unknown keys, naming them and the allowed ones."""
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown} (allowed: {', '.join(allowed)})")


class SensorNoise:
    """Additive white Gaussian noise on length (``length_noise_mm``) and resistance
    (``resistance_noise_ohm``), standard deviations; zero disables either."""

    def __init__(self, length_noise_mm: float, resistance_noise_ohm: float, rng: random.Random) -> None:
        self.length_noise_mm = length_noise_mm
        self.resistance_noise_ohm = resistance_noise_ohm
        self._gauss = rng.gauss

    def apply(self, inputs: PlantInputs, reading: PlantReading) -> PlantReading:
        length, resistance = reading.length_mm, reading.resistance_ohm
        if self.length_noise_mm:
            length += self._gauss(0.0, self.length_noise_mm)
        if self.resistance_noise_ohm:
            resistance += self._gauss(0.0, self.resistance_noise_ohm)
        return PlantReading(length, resistance)


@register_effect("sensor_noise")
def _sensor_noise(params: Mapping[str, Any], rng: random.Random) -> SensorNoise:
    where = "plant.effects[sensor_noise]"
    check_keys(params, ("length_noise_mm", "resistance_noise_ohm"), where)
    return SensorNoise(number_param(params, "length_noise_mm", where, 0.0, minimum=0.0),
                       number_param(params, "resistance_noise_ohm", where, 0.0, minimum=0.0), rng)
