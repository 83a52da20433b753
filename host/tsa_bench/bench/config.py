"""Bench configuration: which backend, serial settings, geometry, calibration, limits.

A bench file (``configs/bench/*.yaml``) describes one rig. Contract: every physical
quantity carries its unit in its key; calibrations are linear maps from the device's
raw counts to physical units, applied on the host (the device reports raw counts);
``plant`` is read only by the simulated benches (``sim`` and ``simavr``), ``simavr``
only by the firmware-in-the-loop bench (:mod:`tsa_bench.simavr`). Errors name the file and the key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from tsa_bench.plan.limits import Limits

#: Where the shipped bench files live when running from a source checkout.
CONFIG_DIR = Path(__file__).resolve().parents[3] / "configs" / "bench"
BACKENDS = ("sim", "serial", "simavr")


class BenchConfigError(ValueError):
    """A bench file that cannot be used; the message names file and key."""


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
    """CS5513 counts -> string resistance: ``R_ohm = ohm_per_count * counts``.

    ``ohm_per_count = V_ref / 2^19 / I_sense`` for the 20-bit bipolar converter across
    the constant sense current ``sense_current_A``.
    """

    ohm_per_count: float
    sense_current_A: float
    adc_bits: int = 20

    def resistance_ohm(self, counts: Any) -> Any:
        return self.ohm_per_count * counts

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


def _get(data: dict, key: str, where: str, kind: type | tuple, default: Any = ...) -> Any:
    if key not in data:
        if default is ...:
            raise BenchConfigError(f"{where}: missing required key '{key}'")
        return default
    value = data[key]
    if kind in (float, (int, float)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise BenchConfigError(f"{where}: '{key}' must be a finite number, got {value!r}")
        return float(value)
    if kind is int and (isinstance(value, bool) or not isinstance(value, int)):
        raise BenchConfigError(f"{where}: '{key}' must be an integer, got {value!r}")
    if kind is dict and not isinstance(value, dict):
        raise BenchConfigError(f"{where}: '{key}' must be a mapping, got {value!r}")
    return value


def parse_bench(text: str, filename: str = "<string>") -> BenchConfig:
    """Parse bench YAML text; raise BenchConfigError naming file and key."""
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise BenchConfigError(f"{filename}: not valid YAML: {exc}") from None
    if not isinstance(data, dict):
        raise BenchConfigError(f"{filename}: a bench file is a mapping of keys")
    known = {"name", "backend", "port", "baud", "steps_per_turn", "limits", "watchdog_s", "queue_slots",
             "position_sensor", "resistance_sensor", "ack_timeout_s", "boot_timeout_s", "plant", "simavr"}
    for key in data:
        if key not in known:
            raise BenchConfigError(f"{filename}: unknown key '{key}' (allowed: {', '.join(sorted(known))})")
    backend = _get(data, "backend", filename, str)
    if backend not in BACKENDS:
        raise BenchConfigError(f"{filename}: backend '{backend}' must be one of {BACKENDS}")
    limits_map = _get(data, "limits", filename, dict)
    try:
        limits = Limits(**limits_map)
    except (TypeError, ValueError) as exc:
        raise BenchConfigError(f"{filename}: limits: {exc}") from None
    pos = _get(data, "position_sensor", filename, dict)
    res = _get(data, "resistance_sensor", filename, dict)
    where_p, where_r = f"{filename}: position_sensor", f"{filename}: resistance_sensor"
    steps_per_turn = _get(data, "steps_per_turn", filename, int)
    if not 1 <= steps_per_turn <= 65535:
        raise BenchConfigError(f"{filename}: steps_per_turn {steps_per_turn} outside 1..65535")
    current = _get(res, "sense_current_A", where_r, float)
    vref = _get(res, "vref_V", where_r, float)
    if current <= 0 or vref <= 0:
        raise BenchConfigError(f"{where_r}: sense_current_A and vref_V must be > 0")
    bits = _get(res, "adc_bits", where_r, int, 20)
    return BenchConfig(
        name=str(_get(data, "name", filename, str)),
        backend=backend,
        port=data.get("port"),
        baud=_get(data, "baud", filename, int, 250000),
        steps_per_turn=steps_per_turn,
        limits=limits,
        watchdog_s=_get(data, "watchdog_s", filename, float, 2.0),
        queue_slots=_get(data, "queue_slots", filename, int, 16),
        position=PositionCalibration(
            mm_per_count=_get(pos, "mm_per_count", where_p, float),
            offset_mm=_get(pos, "offset_mm", where_p, float),
        ),
        resistance=ResistanceCalibration(
            ohm_per_count=vref / 2 ** (bits - 1) / current, sense_current_A=current, adc_bits=bits),
        ack_timeout_s=_get(data, "ack_timeout_s", filename, float, 0.25),
        boot_timeout_s=_get(data, "boot_timeout_s", filename, float, 3.0),
        plant=_get(data, "plant", filename, dict, {}),
        simavr=_get(data, "simavr", filename, dict, {}),
        source_text=text,
        path=filename,
    )


def load_bench(path: str | Path | None = None) -> BenchConfig:
    """Load a bench file; ``None`` means the shipped simulated bench (configs/bench/sim.yaml)."""
    p = Path(path) if path is not None else CONFIG_DIR / "sim.yaml"
    try:
        text = p.read_text()
    except FileNotFoundError:
        raise BenchConfigError(f"{p}: bench file not found") from None
    except OSError as exc:
        raise BenchConfigError(f"{p}: cannot read bench file: {exc}") from None
    return parse_bench(text, str(p))
