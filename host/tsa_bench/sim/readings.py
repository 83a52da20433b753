"""Value types passed between the plant, its effects and the simulated sensors.

Units: length in mm, resistance in ohm. Contract: immutable; ``PlantReading`` is what
the transducers see at one instant, before analogue-to-digital conversion (a named
tuple: made once per sample, so it has to be cheap).
"""

from __future__ import annotations

from typing import NamedTuple


class PlantReading(NamedTuple):
    """TSA length (mm) and string resistance (ohm) at one instant."""

    length_mm: float
    resistance_ohm: float
