"""Effects of the independent generator: library effects in other forms, and effects the
library does not have. Each acts on whole arrays of one run (numpy; loops where state).

Units: time in s, twist in turns, length in mm, resistance in ohm, torque in N m.

Stages, in order: ``motor`` (actual twist from the commanded one), ``twist`` (the twist
the strings feel), ``length`` (after the kinematics), ``resistance``, ``sensor``
(what the transducers add). Every effect's ``apply(run)`` edits the :class:`PlantRun`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tests.analysis.foreign.rig import Rig, load_torque_Nm


@dataclass
class PlantRun:
    """Arrays of one run while the plant is evaluated (edited in place by effects)."""

    rig: Rig
    t: np.ndarray
    turns_cmd: np.ndarray
    load_g: np.ndarray
    volts: np.ndarray
    moving: np.ndarray
    turns: np.ndarray             # actual motor twist
    twist: np.ndarray             # twist the strings feel
    length: np.ndarray | None = None
    resistance: np.ndarray | None = None
    rng: np.random.Generator | None = None

    def since_stop(self) -> np.ndarray:
        """Seconds since the motor last stopped (0 while moving, inf before the first stop)."""
        mv = self.moving.astype(bool)
        n = len(self.t)
        stop = np.where(np.r_[False, mv[:-1] & ~mv[1:]], np.arange(n), -1)
        np.maximum.accumulate(stop, out=stop)
        out = np.where(stop >= 0, self.t - self.t[np.maximum(stop, 0)], np.inf)
        return np.where(mv, 0.0, out)


def _lowpass(x: np.ndarray, t: np.ndarray, tau: float) -> np.ndarray:
    """Exact first-order lag of a piecewise-constant input."""
    y = np.empty_like(x)
    acc = x[0]
    a = np.exp(-np.diff(t, prepend=t[0]) / tau)
    for i in range(len(x)):
        acc = a[i] * acc + (1.0 - a[i]) * x[i]
        y[i] = acc
    return y


class Effect:
    stage = ""
    family = ""        # the library effect this is a form of ("" = not in the library)

    def apply(self, run: PlantRun) -> None:  # pragma: no cover - abstract
        raise NotImplementedError


# ------------------------------------------------------------------ motor stage

def _torque_table(rig: Rig, loads: np.ndarray, top: float):
    grid = np.linspace(0.0, top, 1500)
    return grid, {m: load_torque_Nm(rig, grid, np.full_like(grid, m)) for m in np.unique(loads)}


@dataclass
class PullOutSlip(Effect):
    """Steps lost while moving when the load torque exceeds the pull-out torque, which
    falls linearly with speed: ``T_po = T0 (1 - w / w_max)``; the move keeps
    ``(T_po / T)^2`` of each increment that would exceed it (the rotor slips)."""

    torque0_Nm: float
    max_speed_turns_per_s: float = 8.0
    stage = "motor"
    family = "missed_steps"

    def apply(self, run: PlantRun) -> None:
        cmd, dt = run.turns_cmd, np.diff(run.t, prepend=run.t[0])
        grid, table = _torque_table(run.rig, run.load_g, float(np.max(np.abs(cmd))) * 1.2 + 1.0)
        act = np.empty_like(cmd)
        a = cmd[0]
        for i in range(len(cmd)):
            d = cmd[i] - (cmd[i - 1] if i else cmd[0])
            want = a + d
            if d != 0.0 and abs(want) > abs(a) and dt[i] > 0:
                w = abs(d) / dt[i]
                t_po = self.torque0_Nm * max(0.05, 1.0 - w / self.max_speed_turns_per_s)
                tau = float(np.interp(abs(want), grid, table[run.load_g[i]]))
                if tau > t_po:
                    want = a + d * (t_po / tau) ** 2
            a = want
            act[i] = a
        run.turns = act


@dataclass
class SaturatingSlip(Effect):
    """Above a twist threshold the motor keeps less and less of each twisting increment:
    lost fraction ``s (1 - exp(-(|n| - n_s) / w))`` (saturating slip)."""

    threshold_turns: float
    slip: float = 0.5
    width_turns: float = 3.0
    stage = "motor"
    family = "missed_steps"

    def apply(self, run: PlantRun) -> None:
        cmd = run.turns_cmd
        act = np.empty_like(cmd)
        a = cmd[0]
        for i in range(len(cmd)):
            d = cmd[i] - (cmd[i - 1] if i else cmd[0])
            if d != 0.0 and abs(a + d) > abs(a) and abs(a) > self.threshold_turns:
                d *= 1.0 - self.slip * (1.0 - np.exp(-(abs(a) - self.threshold_turns) / self.width_turns))
            a += d
            act[i] = a
        run.turns = act


# ------------------------------------------------------------------ twist stage

@dataclass
class TwistCreep(Effect):
    """The strings follow a twist change partly at once, partly by creeping with two time
    constants: the felt twist is ``n - g (n - (n_f1 + n_f2) / 2)`` (length creep after
    twist changes)."""

    fraction: float = 0.15
    tau1_s: float = 8.0
    tau2_s: float = 70.0
    stage = "twist"
    family = "length_creep"

    def apply(self, run: PlantRun) -> None:
        n = run.twist
        f = 0.5 * (_lowpass(n, run.t, self.tau1_s) + _lowpass(n, run.t, self.tau2_s))
        run.twist = n - self.fraction * (n - f)


# ------------------------------------------------------------------ resistance stage

@dataclass
class StretchedTransient(Effect):
    """After each stop the resistance is up by ``A exp(-(t / tau)^beta)`` (stretched exponential)."""

    amp_ohm: float
    tau_s: float = 12.0
    beta: float = 0.55
    stage = "resistance"
    family = "resistance_transient_decay"

    def apply(self, run: PlantRun) -> None:
        s = run.since_stop()
        ok = np.isfinite(s) & ~run.moving.astype(bool)
        run.resistance[ok] += self.amp_ohm * np.exp(-(s[ok] / self.tau_s) ** self.beta)


@dataclass
class TwoExpTransient(Effect):
    """After each stop the resistance is up by ``a1 exp(-t / tau1) + a2 exp(-t / tau2)``."""

    a1_ohm: float
    tau1_s: float
    a2_ohm: float
    tau2_s: float
    stage = "resistance"
    family = "resistance_transient_decay"

    def apply(self, run: PlantRun) -> None:
        s = run.since_stop()
        ok = np.isfinite(s) & ~run.moving.astype(bool)
        run.resistance[ok] += self.a1_ohm * np.exp(-s[ok] / self.tau1_s) + self.a2_ohm * np.exp(-s[ok] / self.tau2_s)


@dataclass
class TimeCreep(Effect):
    """The resistance creeps up with time under tension: ``rate tau (1 - exp(-t / tau))``."""

    ohm_per_hour: float
    tau_s: float = 2400.0
    stage = "resistance"
    family = "resistance_creep"

    def apply(self, run: PlantRun) -> None:
        run.resistance += self.ohm_per_hour / 3600.0 * self.tau_s * (1.0 - np.exp(-(run.t - run.t[0]) / self.tau_s))


@dataclass
class ContactJumps(Effect):
    """Intermittent contact: at random times the resistance jumps up by ``jump`` and stays
    there for a random time (telegraph process). Not a library effect."""

    jump_ohm: float
    per_minute: float = 0.8
    mean_duration_s: float = 20.0
    stage = "resistance"
    family = ""

    def apply(self, run: PlantRun) -> None:
        rng = run.rng
        t = run.t
        extra = np.zeros(len(t))
        now = t[0] + rng.exponential(60.0 / self.per_minute)
        while now < t[-1]:
            dur = rng.exponential(self.mean_duration_s) + 2.0
            size = self.jump_ohm * rng.uniform(0.6, 1.4)
            extra[(t >= now) & (t < now + dur)] += size
            now += dur + rng.exponential(60.0 / self.per_minute)
        run.resistance += extra


# ------------------------------------------------------------------ sensor stage

@dataclass
class GainDrift(Effect):
    """The position sensor's gain drifts: ``reading = o + (X - o)(1 + d t)``. Not a library effect."""

    percent_per_hour: float
    offset_mm: float = 120.0
    stage = "sensor"
    family = ""

    def apply(self, run: PlantRun) -> None:
        g = 1.0 + self.percent_per_hour / 100.0 * (run.t - run.t[0]) / 3600.0
        run.length = self.offset_mm + (run.length - self.offset_mm) * g


@dataclass
class Eccentricity(Effect):
    """An eccentric motor shaft moves the top attachment once per turn:
    ``reading += e sin(2 pi n + phi)``. Not a library effect."""

    amplitude_mm: float
    phase_rad: float = 0.7
    stage = "sensor"
    family = ""

    def apply(self, run: PlantRun) -> None:
        run.length = run.length + self.amplitude_mm * np.sin(2.0 * np.pi * run.turns + self.phase_rad)


STAGES = ("motor", "twist", "length", "resistance", "sensor")
