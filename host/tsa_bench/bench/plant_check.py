"""Validate a simulated bench's plant before any run: build it, then run it once.

Why run it: each plant parameter is checked by its effect (type, sign), but a set of
finite values can still make the simulation produce infinities (a stiffness of
1e-300 N, a radius of 1e300 mm). :func:`check_plant` samples a fresh copy of the
plant across the bench's twist and heater limits and through the simulated sensors,
so `validate` refuses any plant that `run` could not simulate.
"""

from __future__ import annotations

import math
import re
from typing import TYPE_CHECKING

from tsa_bench.userfiles import YamlDocument

if TYPE_CHECKING:
    from tsa_bench.benchdata import BenchConfig

_WHERE = re.compile(r"^(plant(?:\.\w+)*)(?::\s*(?:unknown key\(s\) \['|')(\w+))?")


def _located(doc: YamlDocument, message: str) -> str:
    """``file:line:col: message``, at the plant key the simulation's message names."""
    m = _WHERE.match(message)
    keys: tuple[str, ...] = ("plant",)
    if m:
        keys = tuple(m.group(1).split(".")) + ((m.group(2),) if m.group(2) else ())
    return f"{doc.where(*keys)}: {message}"


def check_plant(bench: BenchConfig, doc: YamlDocument) -> None:
    """Raise BenchConfigError (placed at the offending key) unless the plant builds and runs."""
    from tsa_bench.bench.errors import BenchConfigError
    from tsa_bench.sim.plant import plant_from_config
    from tsa_bench.sim.sensors import SimSensors

    try:
        plant = plant_from_config(bench.plant, seed=0)
    except (ValueError, TypeError) as exc:
        raise BenchConfigError(_located(doc, str(exc))) from None
    lim = bench.limits
    hi = lim.max_twist_turns if lim.max_twist_turns is not None else 100.0
    lo = lim.min_twist_turns if lim.min_twist_turns is not None else -hi
    volts = lim.max_heater_voltage_V if lim.max_heater_voltage_V is not None else 12.0
    try:
        sensors = SimSensors(bench.position, bench.resistance)
    except ArithmeticError as exc:
        raise BenchConfigError(f"{doc.where('position_sensor')}: the sensor calibrations cannot be inverted for "
                               f"the simulation ({exc})") from None
    t = 0.0
    for turns, heater_V, moving in ((0.0, 0.0, False), (hi, 0.0, True), (hi, 0.0, False), (hi, volts, False),
                                    (lo, 0.0, True), (lo, volts, False), (0.0, 0.0, False)):
        t += 1.0
        try:
            reading = plant.sample(t, turns, heater_V, moving)
            ok = math.isfinite(reading.length_mm) and math.isfinite(reading.resistance_ohm)
            if ok:
                sensors.convert(reading.length_mm, reading.resistance_ohm, round(heater_V * 1000))
        except (ArithmeticError, ValueError) as exc:
            ok, reading = False, f"{type(exc).__name__}: {exc}"
        if not ok:
            raise BenchConfigError(
                f"{doc.where('plant')}: plant: the simulation gives no finite reading at {turns:g} turns and "
                f"{heater_V:g} V ({reading}); check the plant parameters")
