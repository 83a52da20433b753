"""A bench as configured: its calibrations, limits and settings, as plain data.

Units: every field carries its unit in its name (mm, ohm, A, s, turns); calibrations are
linear maps from the device's raw counts to physical units, applied on the host.

Contract: :class:`BenchConfig` is what a validated bench file (``configs/bench/*.yaml``)
holds; :func:`tsa_bench.bench.load_bench` reads and checks the file and builds it. The
simulated device, the plan checks and the runner take a BenchConfig and never read the file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from tsa_bench.benchdata.limits import Limits


@dataclass(frozen=True)
class PositionCalibration:
    """ADS1115 counts -> TSA length: ``length_mm = offset_mm + mm_per_count * counts``."""

    mm_per_count: float
    offset_mm: float

    def length_mm(self, counts: Any) -> Any:
        return self.offset_mm + self.mm_per_count * counts

    def counts(self, length_mm: float) -> float:
        """Inverse map (unrounded), used by the simulated sensor."""
        return (length_mm - self.offset_mm) / self.mm_per_count


@dataclass(frozen=True)
class ResistanceCalibration:
    """CS5513 counts -> string resistance: ``R_ohm = offset_ohm + gain * ohm_per_count * counts``.

    ``ohm_per_count = V_ref / 2^19 / I_sense`` for the 20-bit bipolar converter across
    the constant sense current ``sense_current_A``; ``gain`` (1) and ``offset_ohm`` (0)
    come from a calibration against reference resistors (``tsa-bench calibrate resistance``).
    """

    ohm_per_count: float
    sense_current_A: float
    adc_bits: int = 20
    gain: float = 1.0
    offset_ohm: float = 0.0

    def resistance_ohm(self, counts: Any) -> Any:
        return self.offset_ohm + self.gain * self.ohm_per_count * counts

    def counts(self, resistance_ohm: float) -> float:
        """Inverse map (unrounded), used by the simulated converter."""
        return (resistance_ohm - self.offset_ohm) / (self.gain * self.ohm_per_count)

    @property
    def max_counts(self) -> int:
        return 2 ** (self.adc_bits - 1) - 1


@dataclass(frozen=True)
class BenchConfig:
    """One rig. ``source_text`` is the YAML exactly as read (stored in the run file)."""

    name: str
    backend: str
    port: str | None
    baud: int
    steps_per_turn: int
    limits: Limits
    watchdog_s: float
    queue_slots: int
    position: PositionCalibration
    resistance: ResistanceCalibration
    ack_timeout_s: float = 0.25
    boot_timeout_s: float = 3.0
    plant: dict[str, Any] = field(default_factory=dict)
    simavr: dict[str, Any] = field(default_factory=dict)
    source_text: str = ""
    path: str | None = None

    def steps(self, turns: float) -> int:
        """Motor turns -> nearest whole microstep."""
        return int(round(turns * self.steps_per_turn))
