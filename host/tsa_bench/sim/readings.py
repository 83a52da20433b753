"""Value types passed between the plant, its effects and the simulated sensors.

Units: length in mm, resistance in ohm. Contract: immutable; ``PlantReading`` is what
the transducers see at one instant, before analogue-to-digital conversion.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class PlantReading:
    """TSA length (mm) and string resistance (ohm) at one instant."""

    length_mm: float
    resistance_ohm: float
