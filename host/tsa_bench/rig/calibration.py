"""`tsa-bench calibrate position | resistance`: readings against a reference -> calibration.

Units: length in mm (ruler), resistance in ohm (reference resistors or an ohmmeter),
raw counts as the device reports them, twist in turns.

Contract: a calibration point pairs the mean raw counts the device reports over
``seconds`` of samples with the reference value a person reads. :func:`fit_position`
fits ``length_mm = offset_mm + mm_per_count * counts`` and :func:`fit_resistance`
``R_ohm = offset_ohm + gain * ohm_per_count * counts`` (``ohm_per_count`` from the
converter's reference voltage and sense current) by least squares through two or more
points; both give the residual of every point and their RMS, and refuse points whose
counts do not spread (a sensor that did not change between them) or a result the bench
file could not hold. :func:`acquire` takes the points on a connected rig: optionally
moving to each of ``at_turns`` first (the position sensor then sees the TSA at several
lengths; back to the starting twist at the end), then reading the counts and asking
for the reference value. The device samples only while a point is measured: while a
person reads a ruler it is idle, so no watchdog trips however long that takes.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from tsa_bench.benchdata import BenchConfig
from tsa_bench.protocol import msg

#: How far apart (in counts, peak to peak) the points must lie for a fit, at least; and
#: in standard errors of the points' means when their noise is known.
MIN_COUNT_SPREAD = 2.0
MIN_SPREAD_IN_ERRORS = 10.0


class CalibrationError(ValueError):
    """Points that do not make a calibration; the message says why."""


@dataclass(frozen=True)
class Fit:
    """A fitted calibration and how well it fits its points."""

    quantity: str                        # "position" | "resistance"
    result: dict[str, float]             # the bench-file values
    counts: tuple[float, ...]
    reference: tuple[float, ...]         # mm or ohm
    fitted: tuple[float, ...]
    unit: str

    @property
    def residuals(self) -> tuple[float, ...]:
        return tuple(r - f for r, f in zip(self.reference, self.fitted))

    @property
    def rms_residual(self) -> float:
        return float(np.sqrt(np.mean(np.square(self.residuals))))

    def record(self, device: str = "", note: str = "") -> dict:
        """The calibration record for the bench file (:mod:`tsa_bench.bench.records`)."""
        name = "length_mm" if self.quantity == "position" else "resistance_ohm"
        suffix = "mm" if self.quantity == "position" else "ohm"
        points = [{"counts": _round(c), name: _round(r), f"fit_{suffix}": _round(f),
                   f"residual_{suffix}": _round(r - f)}
                  for c, r, f in zip(self.counts, self.reference, self.fitted)]
        rec: dict = {"quantity": self.quantity,
                     "date": dt.datetime.now(dt.timezone.utc).astimezone().isoformat(timespec="seconds")}
        if device:
            rec["device"] = device
        if note:
            rec["note"] = note
        rec["points"] = points
        rec["result"] = {k: _round(v) for k, v in self.result.items()}
        rec[f"rms_residual_{suffix}"] = _round(self.rms_residual)
        return rec


def _round(x: float) -> float:
    return float(f"{x:.10g}")


def _line(counts: Sequence[float], reference: Sequence[float], what: str,
          count_error: float = 0.0) -> tuple[float, float]:
    c = np.asarray(counts, dtype=float)
    r = np.asarray(reference, dtype=float)
    if len(c) < 2 or len(c) != len(r):
        raise CalibrationError(f"a {what} calibration needs two or more points, got {len(c)}")
    if not (np.isfinite(c).all() and np.isfinite(r).all()):
        raise CalibrationError(f"a {what} calibration point is not a finite number")
    need = max(MIN_COUNT_SPREAD, MIN_SPREAD_IN_ERRORS * count_error)
    if np.ptp(c) < need:
        raise CalibrationError(
            f"the counts hardly change between the points ({np.min(c):.1f}..{np.max(c):.1f}, less than {need:.1f} "
            f"apart given the sensor's noise): the sensor did not see different {what}s - change the {what} more "
            "between the points")
    slope, intercept = np.polyfit(c, r, 1)
    return float(slope), float(intercept)


def fit_position(counts: Sequence[float], length_mm: Sequence[float], count_error: float = 0.0) -> Fit:
    """``length_mm = offset_mm + mm_per_count * counts`` (module contract); ``count_error``:
    the largest standard error of a point's mean counts (0: unknown)."""
    slope, offset = _line(counts, length_mm, "length", count_error)
    if not 1e-9 <= abs(slope) <= 1e3:
        raise CalibrationError(f"the fit gives {slope:g} mm/count, outside 1e-9..1e3 in magnitude: "
                               "check the ruler readings")
    fitted = offset + slope * np.asarray(counts, dtype=float)
    return Fit("position", {"mm_per_count": slope, "offset_mm": offset}, tuple(map(float, counts)),
               tuple(map(float, length_mm)), tuple(map(float, fitted)), "mm")


def fit_resistance(counts: Sequence[float], resistance_ohm: Sequence[float], ohm_per_count: float,
                   count_error: float = 0.0) -> Fit:
    """``R_ohm = offset_ohm + gain * ohm_per_count * counts`` (module contract)."""
    slope, offset = _line(counts, resistance_ohm, "resistance", count_error)
    gain = slope / ohm_per_count
    if not 1e-3 <= gain <= 1e3:
        raise CalibrationError(f"the fit gives a gain of {gain:g} on the converter's {ohm_per_count:g} ohm/count, "
                               "outside 1e-3..1e3: check the reference values and sense_current_A / vref_V")
    if not -1e6 <= offset <= 1e6:
        raise CalibrationError(f"the fit gives an offset of {offset:g} ohm: check the reference values")
    fitted = offset + slope * np.asarray(counts, dtype=float)
    return Fit("resistance", {"gain": gain, "offset_ohm": offset}, tuple(map(float, counts)),
               tuple(map(float, resistance_ohm)), tuple(map(float, fitted)), "ohm")


def mean_counts(samples: Sequence[msg.Sample], quantity: str) -> tuple[float, float]:
    """Mean raw counts of the readings that are valid for ``quantity``, and its standard error."""
    if quantity == "position":
        ok = [s.position_raw for s in samples if not s.adc_flags & msg.AdcFlags.POSITION_INVALID]
    else:
        bad = msg.AdcFlags.RESISTANCE_NOT_MEASURED | msg.AdcFlags.RESISTANCE_OVERRANGE
        ok = [s.resistance_raw for s in samples if not s.adc_flags & bad]
    if not ok:
        raise CalibrationError(f"no valid {quantity} reading in {len(samples)} samples: check the sensor "
                               "(tsa-bench check)")
    return float(np.mean(ok)), float(np.std(ok) / np.sqrt(len(ok)))


def parse_reference(text: str, unit: str) -> float | None:
    """The number a person typed (None: they are done); CalibrationError if it is not one."""
    text = text.strip()
    if not text:
        return None
    if text.lower().endswith(unit.lower()):
        text = text[: -len(unit)].strip()
    try:
        value = float(text)
    except ValueError:
        raise CalibrationError(f"{text!r} is not a number of {unit}") from None
    if not np.isfinite(value):
        raise CalibrationError(f"{text!r} is not a finite number of {unit}")
    return value


def acquire(link, quantity: str, ask: Callable[[str], str], *, at_turns: Sequence[float] = (),
            seconds: float = 1.0, rate_turns_per_s: float = 1.0, accel_turns_per_s2: float = 10.0,
            say: Callable[[str], None] = print,
            kept: list[tuple[float, float]] | None = None) -> tuple[list[float], list[float], float]:
    """Take calibration points on a connected :class:`~tsa_bench.rig.link.RigLink` (module contract):
    (mean counts, reference values, the largest standard error of a point's mean counts).
    Each point is also appended to ``kept`` (counts, reference) the moment it is complete,
    so a caller still has the points when the rig fails later (an exception from here)."""
    unit = "mm" if quantity == "position" else "ohm"
    what = "ruler length" if quantity == "position" else "reference resistance"
    counts: list[float] = []
    refs: list[float] = []
    kept = [] if kept is None else kept
    error = 0.0
    period_s = min(0.1, max(0.01, seconds / 10))

    def measure(sampling: bool = False) -> tuple[float, float]:
        # sampling while the rig moves and measures (the samples keep the link's clock
        # going), off while a person reads the ruler: the device is idle then, so its
        # watchdog cannot trip however long the reading takes
        if not sampling:
            link.set_sampling(period_s)
        got = link.samples(seconds)
        link.set_sampling(0)
        return mean_counts(got, quantity)

    start_turns = link.status().step_position / link.steps_per_turn
    try:
        targets = list(at_turns) if at_turns else [None] * 10_000
        for i, turns in enumerate(targets):
            if turns is not None:
                say(f"point {i + 1}: moving to {turns:g} turns")
                link.set_sampling(period_s)
                link.move_to(turns, rate_turns_per_s, accel_turns_per_s2)
                link.wait_idle(600.0)
                c, se = measure(sampling=True)
                value = parse_reference(ask(f"{what} now ({unit}): "), unit)
                if value is None:
                    break
            else:
                value = parse_reference(ask(f"point {i + 1}: set it up, then type the {what} ({unit}); "
                                            "Enter alone when done: "), unit)
                if value is None:
                    break
                c, se = measure()
            say(f"point {i + 1}: {c:.2f} counts = {value:g} {unit}")
            counts.append(c)
            refs.append(value)
            kept.append((c, value))
            error = max(error, se)
    finally:
        if at_turns:
            link.set_sampling(period_s)
            link.move_to(start_turns, rate_turns_per_s, accel_turns_per_s2)
            link.wait_idle(600.0)
        link.set_sampling(0)
    return counts, refs, error


def device_text(link) -> str:
    ident = link.identity
    return f"firmware {ident.fw_major}.{ident.fw_minor}.{ident.fw_patch} on {link.port_name}"


def fit_for(quantity: str, counts: Sequence[float], refs: Sequence[float], bench: BenchConfig,
            count_error: float = 0.0) -> Fit:
    if quantity == "position":
        return fit_position(counts, refs, count_error)
    return fit_resistance(counts, refs, bench.resistance.ohm_per_count, count_error)


def points_text(points: Sequence[tuple[float, float]]) -> str:
    """The points as ``--points`` takes them (counts=reference, ...), re-fitted without the rig."""
    return ",".join(f"{c:.6g}={r:.10g}" for c, r in points)
