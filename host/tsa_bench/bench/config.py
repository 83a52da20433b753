"""Bench configuration: which backend, serial settings, geometry, calibration, limits.

A bench file (``configs/bench/*.yaml``) describes one rig. Contract: every physical
quantity carries its unit in its key; calibrations are linear maps from the device's
raw counts to physical units, applied on the host (the device reports raw counts);
``plant`` is read only by the simulated benches (``sim`` and ``simavr``), ``simavr``
only by the firmware-in-the-loop bench (:mod:`tsa_bench.simavr`).

:func:`load_bench` / :func:`parse_bench` read the file with the hardened YAML reader
(:mod:`tsa_bench.userfiles`) and validate all of it before anything is used: every
key and value (finite numbers in range, limits the wire protocol can carry), the
``port`` (:mod:`tsa_bench.bench.ports`), the ``plant`` of a simulated bench (built and
sampled once across the bench limits, so a plant that cannot run is refused here and
not half-way through a run) and the ``simavr`` section of a firmware-in-the-loop
bench. Every error is one line ``file:line:col: key: what``; one :class:`BenchConfigError`
lists the errors of every section at once, in file order (within a section, the first).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from tsa_bench.bench.errors import BenchConfigError
from tsa_bench.bench.ports import PortPolicyError, check_port
from tsa_bench.bench.records import check_records
from tsa_bench.userfiles import DocumentError, YamlDocument, parse_yaml, read_text_file
from tsa_bench.benchdata import BenchConfig, Limits, PositionCalibration, ResistanceCalibration
from tsa_bench.shipped import shipped

#: Where the shipped bench files live (the source tree's configs/bench, or the wheel's copy).
CONFIG_DIR = shipped("bench")
BACKENDS = ("sim", "serial", "simavr")
KNOWN_KEYS = ("name", "backend", "port", "baud", "steps_per_turn", "limits", "watchdog_s", "queue_slots",
              "position_sensor", "resistance_sensor", "ack_timeout_s", "boot_timeout_s", "plant", "simavr",
              "calibrations")
# What the wire protocol can carry (protocol/messages.md): i32 steps, u32 step rates,
# u16 mV heater voltage, u16 ms watchdog, u8 queue slots.
I32_MAX, U32_MAX, U16_MAX, U8_MAX = 2**31 - 1, 2**32 - 1, 2**16 - 1, 2**8 - 1


class _Fields:
    """Typed reads from the bench data, each error placed at its key in the file."""

    def __init__(self, doc: YamlDocument) -> None:
        self.doc = doc

    def fail(self, path: tuple[str, ...], message: str) -> BenchConfigError:
        return BenchConfigError(f"{self.doc.where(*path)}: {'.'.join(path)}: {message}")

    def get(self, data: dict, path: tuple[str, ...], default: Any = ...) -> Any:
        key = path[-1]
        if key not in data:
            if default is ...:
                where = self.doc.where(*path[:-1]) if len(path) > 1 else self.doc.filename
                scope = f"{'.'.join(path[:-1])}: " if len(path) > 1 else ""
                raise BenchConfigError(f"{where}: {scope}missing required key '{key}'")
            return default
        return data[key]

    def number(self, data: dict, path: tuple[str, ...], default: Any = ..., *, gt: float | None = None,
               ge: float | None = None, le: float | None = None, unit: str = "") -> float:
        value = self.get(data, path, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
            raise self.fail(path, f"must be a finite number, got {value!r}")
        value = float(value)
        u = f" {unit}" if unit else ""
        if gt is not None and not value > gt:
            raise self.fail(path, f"must be > {gt:g}{u}, got {value:g}")
        if ge is not None and value < ge:
            raise self.fail(path, f"must be >= {ge:g}{u}, got {value:g}")
        if le is not None and value > le:
            raise self.fail(path, f"must be <= {le:g}{u}, got {value:g}")
        return value

    def integer(self, data: dict, path: tuple[str, ...], default: Any = ..., *, lo: int, hi: int) -> int:
        value = self.get(data, path, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(path, f"must be an integer, got {value!r}")
        if not lo <= value <= hi:
            raise self.fail(path, f"{value} is outside {lo}..{hi}")
        return value

    def mapping(self, data: dict, path: tuple[str, ...], default: Any = ...) -> dict:
        value = self.get(data, path, default)
        if value is None and default is not ...:
            return {}
        if not isinstance(value, dict):
            raise self.fail(path, f"must be a mapping, got {value!r}")
        return value

    def text(self, data: dict, path: tuple[str, ...]) -> str:
        value = self.get(data, path)
        if not isinstance(value, str) or not value.strip():
            raise self.fail(path, f"must be non-empty text, got {value!r}")
        return value


def _limits(f: _Fields, data: dict, steps_per_turn: int) -> Limits:
    raw = f.mapping(data, ("limits",))
    for key in raw:
        if key not in Limits.field_names():
            raise f.fail(("limits", key), f"unknown key (allowed: {', '.join(Limits.field_names())})")
    values = {k: (None if v is None else f.number(raw, ("limits", k))) for k, v in raw.items()}
    wire = {"max_twist_turns": I32_MAX / steps_per_turn, "min_twist_turns": I32_MAX / steps_per_turn,
            "max_rate_turns_per_s": U32_MAX / steps_per_turn, "max_accel_turns_per_s2": U32_MAX / steps_per_turn,
            "max_heater_voltage_V": U16_MAX / 1000}
    for key, value in values.items():
        if value is not None and abs(value) > wire[key]:
            raise f.fail(("limits", key), f"{value:g} is beyond what the device protocol can carry "
                                          f"(at most {wire[key]:.6g} in magnitude with {steps_per_turn} steps/turn)")
    try:
        return Limits(**values)
    except (TypeError, ValueError) as exc:
        raise f.fail(("limits",), str(exc)) from None


def _port(f: _Fields, data: dict, allow_url: bool) -> str | None:
    port = data.get("port")
    if port is None:
        return None
    try:
        return check_port(port, allow_url=allow_url)
    except PortPolicyError as exc:
        raise f.fail(("port",), str(exc)) from None


def _position_key(exc: BenchConfigError) -> tuple[int, int]:
    m = re.match(r"^.*?:(\d+):(\d+): ", str(exc))
    return (int(m.group(1)), int(m.group(2))) if m else (0, 0)


def _backend(f: _Fields, data: dict) -> str:
    backend = f.get(data, ("backend",))
    if backend not in BACKENDS:
        raise f.fail(("backend",), f"{backend!r} must be one of {', '.join(BACKENDS)}")
    return backend


def _section_keys(f: _Fields, data: dict, section: str, allowed: tuple[str, ...]) -> dict:
    values = f.mapping(data, (section,))
    for key in values:
        if key not in allowed:
            raise f.fail((section, key), f"unknown key (allowed: {', '.join(allowed)})")
    return values


def _position(f: _Fields, data: dict) -> PositionCalibration:
    pos = _section_keys(f, data, "position_sensor", ("mm_per_count", "offset_mm"))
    mm_per_count = f.number(pos, ("position_sensor", "mm_per_count"), unit="mm/count")
    if not 1e-9 <= abs(mm_per_count) <= 1e3:  # 1 nm .. 1 m per count
        raise f.fail(("position_sensor", "mm_per_count"), f"must be 1e-9..1e3 mm/count in magnitude, "
                                                          f"got {mm_per_count:g}")
    return PositionCalibration(mm_per_count=mm_per_count,
                               offset_mm=f.number(pos, ("position_sensor", "offset_mm"), ge=-1e9, le=1e9, unit="mm"))


def _resistance(f: _Fields, data: dict) -> ResistanceCalibration:
    res = _section_keys(f, data, "resistance_sensor", ("sense_current_A", "vref_V", "adc_bits", "gain", "offset_ohm"))
    current = f.number(res, ("resistance_sensor", "sense_current_A"), gt=0, le=100.0, unit="A")
    vref = f.number(res, ("resistance_sensor", "vref_V"), gt=0, le=1000.0, unit="V")
    bits = f.integer(res, ("resistance_sensor", "adc_bits"), 20, lo=2, hi=32)
    gain = f.number(res, ("resistance_sensor", "gain"), 1.0, ge=1e-3, le=1e3)
    offset_ohm = f.number(res, ("resistance_sensor", "offset_ohm"), 0.0, ge=-1e6, le=1e6, unit="ohm")
    if not vref / 2 ** (bits - 1) / current >= 1e-15:  # the calibration must be a usable number
        raise f.fail(("resistance_sensor",), f"vref_V / 2^(adc_bits-1) / sense_current_A = "
                                             f"{vref / 2 ** (bits - 1) / current:g} ohm/count is too small")
    return ResistanceCalibration(ohm_per_count=vref / 2 ** (bits - 1) / current, sense_current_A=current,
                                 adc_bits=bits, gain=gain, offset_ohm=offset_ohm)


def parse_bench(text: str, filename: str = "<string>", *, allow_url: bool = False,
                trust_firmware_dir: bool = False) -> BenchConfig:
    """Parse and validate bench YAML text (module contract); raise BenchConfigError."""
    try:
        doc = parse_yaml(text, filename)
        data = doc.data()
    except DocumentError as exc:
        raise BenchConfigError(str(exc)) from None
    if not isinstance(data, dict):
        raise BenchConfigError(f"{filename}: a bench file is a mapping of keys (allowed: {', '.join(KNOWN_KEYS)})")
    f = _Fields(doc)
    errors: list[BenchConfigError] = []

    def take(read, default: Any = None) -> Any:
        """One section's value, or its error recorded and ``default``: every section is checked."""
        try:
            return read()
        except BenchConfigError as exc:
            errors.append(exc)
            return default

    for key in data:
        if key not in KNOWN_KEYS:
            errors.append(f.fail((key,), f"unknown key (allowed: {', '.join(sorted(KNOWN_KEYS))})"))
    backend = take(lambda: _backend(f, data))
    steps_per_turn = take(lambda: f.integer(data, ("steps_per_turn",), lo=1, hi=U16_MAX))
    limits = take(lambda: _limits(f, data, steps_per_turn)) if steps_per_turn is not None else None
    position = take(lambda: _position(f, data))
    resistance = take(lambda: _resistance(f, data))
    values = dict(
        name=take(lambda: f.text(data, ("name",))),
        port=take(lambda: _port(f, data, allow_url)),
        baud=take(lambda: f.integer(data, ("baud",), 250000, lo=1, hi=100_000_000)),
        watchdog_s=take(lambda: f.number(data, ("watchdog_s",), 2.0, ge=0.001, le=U16_MAX / 1000, unit="s")),
        queue_slots=take(lambda: f.integer(data, ("queue_slots",), 16, lo=1, hi=U8_MAX)),
        ack_timeout_s=take(lambda: f.number(data, ("ack_timeout_s",), 0.25, ge=0.001, le=10.0, unit="s")),
        boot_timeout_s=take(lambda: f.number(data, ("boot_timeout_s",), 3.0, ge=0.0, le=600.0, unit="s")),
        plant=take(lambda: f.mapping(data, ("plant",), {}), {}),
        simavr=take(lambda: f.mapping(data, ("simavr",), {}), {}),
    )
    take(lambda: check_records(doc, data.get("calibrations")))
    if errors:
        raise BenchConfigError("\n".join(str(e) for e in sorted(errors, key=_position_key)))
    bench = BenchConfig(backend=backend, steps_per_turn=steps_per_turn, limits=limits, position=position,
                        resistance=resistance, source_text=text, path=filename, **values)
    if bench.backend in ("sim", "simavr") or bench.plant:
        from tsa_bench.bench.plant_check import check_plant  # the simulation, only for simulated benches

        check_plant(bench, doc)
    if bench.backend == "simavr" or bench.simavr:
        from tsa_bench.bench.simavr_section import simavr_settings

        simavr_settings(bench, trust_firmware_dir=trust_firmware_dir)
    return bench


def load_bench(path: str | Path | None = None, *, allow_url: bool = False,
               trust_firmware_dir: bool = False) -> BenchConfig:
    """Load and validate a bench file; ``None`` means the shipped simulated bench (configs/bench/sim.yaml).

    ``allow_url`` lets ``port`` be any pyserial URL; ``trust_firmware_dir`` lets a
    simavr bench build firmware outside this checkout (see the module contract).
    """
    p = Path(path) if path is not None else CONFIG_DIR / "sim.yaml"
    try:
        text = read_text_file(p, "bench file")
    except DocumentError as exc:
        raise BenchConfigError(str(exc)) from None
    return parse_bench(text, str(p), allow_url=allow_url, trust_firmware_dir=trust_firmware_dir)
