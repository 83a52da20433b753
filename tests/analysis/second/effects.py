"""Effects of the second generator, each in a form the library does not have.

Units: mm, ohm, s, turns, g. Amplitudes are given in noise standard deviations of the rig
(``sd``) so that each is clearly above the sensor noise.

Each effect is a function ``(plant, rng) -> None`` acting on a :class:`Plant` (arrays
over the samples) at its stage: ``twist`` (what the strings see), ``length`` (the pair's
axial length), ``resistance`` (the strings' resistance) or ``sensor`` (the readings).
``family`` is the library family an honest diagnosis may name (None: outside the
library; the generator's case table says what must be named).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from tests.analysis.second.protocols import Inputs
from tests.analysis.second.rigs import GRAVITY, Rig, load_torque_Nm


@dataclass
class Plant:
    rig: Rig
    h: Inputs
    twist: np.ndarray
    length: np.ndarray
    resistance: np.ndarray


@dataclass(frozen=True)
class Effect:
    name: str
    stage: str
    family: str | None
    apply: Callable[[Plant, np.random.Generator], None]
    physical: bool = True           # False: an artefact of the measurement


def _since_stop(h: Inputs) -> np.ndarray:
    stop = np.where(np.r_[False, h.moving[:-1] & ~h.moving[1:]], np.arange(len(h)), -1)
    np.maximum.accumulate(stop, out=stop)
    return np.where((stop >= 0) & ~h.moving, h.t - h.t[np.maximum(stop, 0)], np.inf)


def power_transient(rng: np.random.Generator, rig: Rig) -> Effect:
    """After each stop R is up by A (1 + s / tau)^-p (a power law, not the ln^2 law, a stretched
    exponential or two exponentials)."""
    a, tau, p = rng.uniform(20, 35) * rig.resistance_noise_ohm, rng.uniform(2.0, 8.0), rng.uniform(0.6, 1.2)

    def go(pl: Plant, _: np.random.Generator) -> None:
        s = _since_stop(pl.h)
        pl.resistance += np.where(np.isfinite(s), a * (1.0 + np.where(np.isfinite(s), s, 0.0) / tau) ** -p, 0.0)
    return Effect("power-law transient", "resistance", "resistance_transient_decay", go)


def log_creep(rng: np.random.Generator, rig: Rig) -> Effect:
    """Creep by Boltzmann superposition with a logarithmic compliance: every load step dF (the
    first one when the mass is hung at t = 0) adds k dF ln(1 + (t - t_j) / tau) of length."""
    total = rng.uniform(12, 20) * rig.length_noise_mm
    tau = rng.uniform(5.0, 20.0)

    def go(pl: Plant, _: np.random.Generator) -> None:
        f = pl.h.load_g * GRAVITY / 1000.0
        steps = np.flatnonzero(np.diff(np.r_[0.0, f]) != 0)
        k = total / (f[0] * np.log1p((pl.h.t[-1] - pl.h.t[0]) / tau))
        for j in steps:
            df = f[j] - (f[j - 1] if j else 0.0)
            dt = np.clip(pl.h.t - pl.h.t[j], 0.0, None)
            pl.length += np.where(pl.h.t >= pl.h.t[j], k * df * np.log1p(dt / tau), 0.0)
    return Effect("logarithmic creep", "length", "length_creep", go)


def dahl_friction(rng: np.random.Generator, rig: Rig) -> Effect:
    """The strings' twist approaches the motor's exponentially with the twist travelled (scale d
    turns): a smooth friction loop, not a play of fixed width."""
    d = rng.uniform(0.6, 1.2)

    def go(pl: Plant, _: np.random.Generator) -> None:
        n = pl.twist
        e = np.empty_like(n)
        e[0] = n[0]
        decay = np.exp(-np.abs(np.diff(n)) / d)
        for i in range(1, len(n)):
            e[i] = n[i] + (e[i - 1] - n[i]) * decay[i - 1]
        pl.twist = e
    return Effect("Dahl twist friction", "twist", "twist_hysteresis", go)


def sqrt_wear(rng: np.random.Generator, rig: Rig) -> Effect:
    """R rises with the square root of the cumulative twist travel (wear that slows down)."""
    amp = rng.uniform(25, 40) * rig.resistance_noise_ohm

    def go(pl: Plant, _: np.random.Generator) -> None:
        travel = np.cumsum(np.abs(np.diff(pl.h.turns, prepend=pl.h.turns[0])))
        pl.resistance += amp * np.sqrt(travel / travel[-1])
    return Effect("wear with sqrt(travel)", "resistance", "resistance_creep", go)


def torque_slip(rng: np.random.Generator, rig: Rig) -> Effect:
    """While moving, the motor loses twist in proportion to how far the load torque exceeds a limit
    (a fraction of the run's largest torque): lost += g (T - T_lim)/T_lim |dn|."""
    frac, gain = rng.uniform(0.55, 0.7), rng.uniform(0.25, 0.4)

    def go(pl: Plant, _: np.random.Generator) -> None:
        tq = load_torque_Nm(pl.rig, pl.h.turns, pl.h.load_g)
        lim = frac * float(np.max(tq))
        dn = np.abs(np.diff(pl.h.turns, prepend=pl.h.turns[0])) * pl.h.moving
        lost = np.cumsum(gain * np.clip(tq - lim, 0.0, None) / lim * dn)
        pl.twist = pl.twist - np.sign(pl.h.turns) * lost
    return Effect("torque-proportional slip", "twist", "missed_steps", go)


def resistance_gain_drift(rng: np.random.Generator, rig: Rig) -> Effect:
    """Artefact: the resistance channel's gain drifts, R_read = R (1 + g (t - t0) / T)."""
    sign = rng.choice([-1.0, 1.0])
    frac = rng.uniform(25, 40) * rig.resistance_noise_ohm / rig.r_ref_ohm

    def go(pl: Plant, _: np.random.Generator) -> None:
        t = pl.h.t
        pl.resistance *= 1.0 + sign * frac * (t - t[0]) / (t[-1] - t[0])
    return Effect("resistance gain drift", "sensor", "resistance_sensor_drift", go, physical=False)


def length_zero_drift(rng: np.random.Generator, rig: Rig) -> Effect:
    """Artefact: the length channel's zero drifts linearly with time (amplifier warming)."""
    total = rng.choice([-1.0, 1.0]) * rng.uniform(15, 25) * rig.length_noise_mm

    def go(pl: Plant, _: np.random.Generator) -> None:
        t = pl.h.t
        pl.length += total * (t - t[0]) / (t[-1] - t[0])
    return Effect("length zero drift", "sensor", "length_sensor_drift", go, physical=False)


def mains_beat(rng: np.random.Generator, rig: Rig) -> Effect:
    """Outside the library: interference beating with the sampling, R += A sin(2 pi t / P + phi)."""
    amp, period, phase = rng.uniform(6, 10) * rig.resistance_noise_ohm, rng.uniform(25.0, 60.0), rng.uniform(0, 6.3)

    def go(pl: Plant, _: np.random.Generator) -> None:
        pl.resistance += amp * np.sin(2.0 * np.pi * pl.h.t / period + phase)
    return Effect("mains beat", "sensor", None, go, physical=False)


def contact_ripple(rng: np.random.Generator, rig: Rig) -> Effect:
    """Outside the library: a contact at the clamp rubs twice per turn, R += A cos(4 pi n + phi)."""
    amp, phase = rng.uniform(6, 10) * rig.resistance_noise_ohm, rng.uniform(0, 6.3)

    def go(pl: Plant, _: np.random.Generator) -> None:
        pl.resistance += amp * np.cos(4.0 * np.pi * pl.h.turns + phase)
    return Effect("twice-per-turn contact ripple", "resistance", None, go)


def track_wave(rng: np.random.Generator, rig: Rig) -> Effect:
    """Outside the library: the length sensor's track is periodically non-linear,
    X_read = X + A sin(2 pi X / lambda)."""
    amp, lam = rng.uniform(6, 10) * rig.length_noise_mm, rng.uniform(8.0, 15.0)

    def go(pl: Plant, _: np.random.Generator) -> None:
        pl.length += amp * np.sin(2.0 * np.pi * pl.length / lam)
    return Effect("periodic track non-linearity", "sensor", None, go, physical=False)
