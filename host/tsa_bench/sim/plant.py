"""The simulated plant: what a pair of twisted SCP strings does under a hanging load.

Units: time in s, twist in motor turns (signed), heater voltage in V, load in g,
length in mm, resistance in ohm, temperature in degC.

Contract: a :class:`Plant` is told the hanging mass (``set_load``) and sampled with
nondecreasing times; each sample returns the length and resistance the transducers
see. :class:`TsaPlant` holds one :class:`~tsa_bench.sim.effects.PlantState` and a
list of enabled effects (:mod:`tsa_bench.sim.effects`). Per sample it writes the
inputs, runs the ``motor`` effects (actual twist), updates the motion bookkeeping
(direction, time since the motor stopped, cumulative twist travel), runs the
``thermal`` and ``geometry`` effects, computes the TSA length ``X`` from the string
length ``L`` and the effective twist (:func:`~tsa_bench.sim.effects.tsa_length_mm`,
thesis eqs. 4.4-4.5), then the ``length``, ``resistance`` and ``sensor`` effects.
Before the effects, each sample starts from ``L = L0``, ``R = R0``, constant radius,
the actual twist and ambient temperature, so a switched-off effect leaves no trace.
Effects always run in canonical stage order, whatever the config order. The bench
file's ``plant`` mapping is::

    plant: {untwisted_length_mm, radius_mm, resistance_ohm, ambient_C, initial_load_g, seed,
            effects: {<name>: {enabled: bool, <param>: value, ...}, ...}}

Omitted effects and parameters take the defaults documented on each effect class
(``tsa-bench effects``; configs/bench/sim.yaml lists them all): an omitted effect is on,
except the later additions marked ``default_enabled = False`` (twist_stiffening,
thermal_actuation, length_settling, resistance_settling), which a bench file switches on.

Speed: after its first :data:`CHAIN_SAMPLES` samples a plant of library effects runs a
fused kernel (:mod:`tsa_bench.sim.fused`): the same operations in one generated function,
bit-identical to the chain of ``apply`` calls (:meth:`TsaPlant.sample_chain`, the
reference, which a plant with an effect the kernel does not know, or built with
``fused=False``, always runs). About 3 us per sample with the shipped bench's effects
(``python3 scripts/bench/sim_speed.py --plant-only``). :meth:`TsaPlant.sample_block`
samples a whole input history in one call. Reading ``state`` or ``effects`` stops the
kernel (it writes its state back); the next sample restarts it from there, so a reference
to ``state`` kept across samples goes stale: read ``plant.state`` after the sample.
"""

from __future__ import annotations

import copy
import random
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Protocol

from tsa_bench.sim.effects import (EFFECTS, FORMS, Effect, PlantState, build_effect, canonical_order, check_keys,
                                   number_param, parse_effect_config, tsa_length_mm)
from tsa_bench.sim.kinematics import NEWTON_PER_GRAM, TsaGeometry
from tsa_bench.sim.readings import PlantReading

if TYPE_CHECKING:  # the kernel's module is imported when a plant first fuses
    from tsa_bench.sim.fused import Kernel

__all__ = ["Plant", "PlantReading", "TsaPlant", "plant_from_config", "PLANT_KEYS"]

#: Single samples a plant takes through the effect chain before it compiles its fused kernel.
CHAIN_SAMPLES = 16

#: Keys accepted in a bench file's ``plant`` mapping.
PLANT_KEYS = ("untwisted_length_mm", "radius_mm", "resistance_ohm", "ambient_C", "initial_load_g", "seed",
              "effects")


class Plant(Protocol):
    """What the simulated device drives and measures."""

    def set_load(self, load_g: float) -> None:
        """Change the hanging mass (g)."""

    def sample(self, t_s: float, turns: float, heater_voltage_V: float, motor_moving: bool) -> PlantReading:
        """The reading at time ``t_s`` (nondecreasing between calls)."""


class TsaPlant:
    """The TSA kinematics plus a list of effects run in canonical order (module docstring)."""

    def __init__(self, untwisted_length_mm: float = 248.0, radius_mm: float = 0.51, resistance_ohm: float = 5.0,
                 ambient_C: float = 22.0, load_g: float = 0.0,
                 effects: list[Effect] | tuple[Effect, ...] = (), fused: bool = True) -> None:
        if not untwisted_length_mm > 0:
            raise ValueError(f"untwisted_length_mm must be > 0, got {untwisted_length_mm}")
        if not radius_mm >= 0:
            raise ValueError(f"radius_mm must be >= 0, got {radius_mm}")
        order = canonical_order([e.name for e in effects])
        by_name = {e.name: e for e in effects}
        self._effects: tuple[Effect, ...] = tuple(by_name[n] for n in order)
        stages = {}
        for e in self._effects:
            stages.setdefault(e.stage, []).append(e.apply)
        self._motor = tuple(stages.get("motor", ()))
        self._pre = tuple(stages.get("thermal", ())) + tuple(stages.get("geometry", ()))
        self._post = tuple(stages.get("length", ())) + tuple(stages.get("resistance", ()))
        self._sensor = tuple(stages.get("sensor", ()))
        self._state = PlantState(untwisted_length_mm=untwisted_length_mm, radius_mm=radius_mm,
                                 resistance0_ohm=resistance_ohm, ambient_C=ambient_C,
                                 temperature_C=ambient_C, string_length_mm=untwisted_length_mm,
                                 kinematic_length_mm=untwisted_length_mm, length_mm=untwisted_length_mm,
                                 resistance_ohm=resistance_ohm)
        self._t_prev: float | None = None
        self._moving_prev = False
        self._fused = fused
        self._kernel: Kernel | None = None
        self._warmup = CHAIN_SAMPLES
        self.load_g = 0.0
        self.set_load(load_g)

    # -- the fused kernel (tsa_bench.sim.fused) and the state it keeps -----
    def _start(self, block: bool = False) -> Kernel | None:
        """The running kernel (with ``block``, one that has a block loop), built from the present
        state if none runs; None: run the chain (the first :data:`CHAIN_SAMPLES` single samples
        too, so that a plant sampled a few times only is not compiled)."""
        k = self._kernel
        if (k is None or (block and k.block is None)) and self._fused:
            if k is None and not block and self._warmup > 0:
                self._warmup -= 1
                return None
            from tsa_bench.sim.fused import fuse

            self._sync()
            k = fuse(self, block)
            if k is None:
                self._fused = False
                return None
            self._kernel = k
            self.sample = k.sample  # type: ignore[method-assign]  # the instance calls the closure directly
        return k

    def _sync(self) -> None:
        """Write the kernel's state back to ``state``, the effects and the plant, and stop it."""
        k = self._kernel
        if k is not None:
            k.export()
            self._kernel = None
            self.__dict__.pop("sample", None)

    @property
    def state(self) -> PlantState:
        """The shared state after the last sample (reading it stops the fused kernel; the next sample restarts it)."""
        self._sync()
        return self._state

    @property
    def effects(self) -> tuple[Effect, ...]:
        """The enabled effects in canonical order (their memory as of the last sample)."""
        self._sync()
        return self._effects

    def __getstate__(self) -> dict[str, Any]:
        self._sync()
        return dict(self.__dict__)

    # -- configuration views --------------------------------------------
    def effect(self, name: str) -> Effect | None:
        """The enabled effect called ``name``, or None."""
        for e in self.effects:
            if e.name == name:
                return e
        return None

    @property
    def geometry(self) -> TsaGeometry:
        """L0, r0 and the compliance K (huge if string_compliance is off)."""
        comp = self.effect("string_compliance")
        k = comp.params.stiffness_N if comp is not None else 1e300
        return TsaGeometry(self._state.untwisted_length_mm, self._state.radius_mm, k)

    def reset(self) -> None:
        """Back to power-up: effects forget their memory, time restarts (load kept)."""
        self._sync()
        for e in self._effects:
            e.reset()
        s = self._state
        s.t_s = s.dt_s = s.travel_turns = s.contraction = 0.0
        s.turns = s.turns_cmd = s.turns_eff = 0.0
        s.t_since_stop_s = float("inf")
        s.temperature_C = s.ambient_C
        self._t_prev = None
        self._moving_prev = False

    def set_load(self, load_g: float) -> None:
        if not load_g >= 0:
            raise ValueError(f"load_g must be >= 0, got {load_g}")
        self.load_g = float(load_g)
        self._state.load_g = self.load_g
        self._state.load_N = self.load_g * NEWTON_PER_GRAM
        if self._kernel is not None:
            self._kernel.set_load(self.load_g, self._state.load_N)

    def peek(self, turns: float, heater_voltage_V: float | None = None) -> PlantReading:
        """The noise-free reading if the plant were at ``turns`` now (nothing changes).

        Runs one sample on a copy of the plant at the last sample time (no time passes,
        motor state unchanged), without the sensor stage.
        """
        clone = copy.deepcopy(self)
        clone._sensor = ()
        clone._fused = False
        s = clone._state
        volts = s.heater_voltage_V if heater_voltage_V is None else heater_voltage_V
        return clone.sample(s.t_s if clone._t_prev is not None else 0.0, turns, volts, clone._moving_prev)

    def quasi_static(self, turns: float) -> PlantReading:
        """Steady noise-free reading at ``turns`` given the plant's present memory (see :meth:`peek`)."""
        return self.peek(turns)

    # -- the sample ------------------------------------------------------
    def sample(self, t_s: float, turns: float, heater_voltage_V: float, motor_moving: bool) -> PlantReading:
        """The reading at ``t_s`` (s, nondecreasing) with the motor at ``turns`` (commanded), the heater
        at ``heater_voltage_V`` and the motor turning or not (fused kernel, else the effect chain)."""
        k = self._start()
        if k is None:
            return self.sample_chain(t_s, turns, heater_voltage_V, motor_moving)
        return k.sample(t_s, turns, heater_voltage_V, motor_moving)

    def sample_block(self, t_s: Any, turns: Any, heater_voltage_V: Any, motor_moving: Any,
                     state: bool = False) -> dict[str, Any]:
        """Samples at the times ``t_s`` (array, s); the other inputs are arrays of the same length or
        scalars. Returns numpy arrays ``length_mm`` and ``resistance_ohm`` (and, with ``state``,
        ``temperature_C`` and ``turns_actual``), equal to calling :meth:`sample` at each time."""
        import numpy as np

        t = np.asarray(t_s, dtype=float)
        n = t.shape[0]
        ts = t.tolist()
        cmds = np.broadcast_to(np.asarray(turns, dtype=float), (n,)).tolist()
        vs = np.broadcast_to(np.asarray(heater_voltage_V, dtype=float), (n,)).tolist()
        ms = np.broadcast_to(np.asarray(motor_moving, dtype=bool), (n,)).tolist()
        out_l: list[float] = []
        out_r: list[float] = []
        out_t: list[float] | None = [] if state else None
        out_a: list[float] | None = [] if state else None
        k = self._start(block=True)
        if k is not None:
            k.block(ts, cmds, vs, ms, out_l, out_r, out_t, out_a)
        else:
            st = self._state
            for args in zip(ts, cmds, vs, ms):
                length, resistance = self.sample_chain(*args)
                out_l.append(length)
                out_r.append(resistance)
                if state:
                    out_t.append(st.temperature_C)  # type: ignore[union-attr]
                    out_a.append(st.turns)  # type: ignore[union-attr]
        out = {"length_mm": np.array(out_l, dtype=float), "resistance_ohm": np.array(out_r, dtype=float)}
        if state:
            out["temperature_C"] = np.array(out_t, dtype=float)
            out["turns_actual"] = np.array(out_a, dtype=float)
        return out

    def sample_chain(self, t_s: float, turns: float, heater_voltage_V: float, motor_moving: bool) -> PlantReading:
        """:meth:`sample` by running each effect's ``apply`` on the shared state in turn (the reference
        the fused kernel equals bit for bit; the path for effects the kernel does not know)."""
        self._sync()
        s = self._state
        t_prev = self._t_prev
        s.dt_s = dt = 0.0 if t_prev is None or t_s < t_prev else t_s - t_prev
        self._t_prev = t_s
        s.t_s = t_s
        s.turns_cmd = turns
        s.heater_voltage_V = heater_voltage_V
        s.motor_moving = motor_moving = bool(motor_moving)
        prev_turns = s.turns
        s.turns = turns
        for apply in self._motor:
            apply(s)
        # motion bookkeeping, on the actual twist
        actual = s.turns
        d = abs(actual) - abs(prev_turns)
        s.direction = 1 if d > 0.0 else -1 if d < 0.0 else 0
        s.travel_turns += abs(actual - prev_turns) if t_prev is not None else abs(actual)
        if motor_moving:
            s.t_since_stop_s = 0.0
        elif self._moving_prev:
            s.t_since_stop_s = 0.0
        else:
            s.t_since_stop_s += dt
        self._moving_prev = motor_moving
        # fresh per-sample quantities, then thermal + geometry
        s.turns_eff = actual
        s.string_length_mm = s.untwisted_length_mm
        s.radius_growth = False
        s.stiffness_factor = 1.0
        s.hysteresis_scale = 1.0
        if self._pre:
            for apply in self._pre:
                apply(s)
        # kinematics
        big_l = s.string_length_mm
        x = tsa_length_mm(big_l, s.turns_eff, s.radius_mm, s.untwisted_length_mm, s.radius_growth)
        s.kinematic_length_mm = s.length_mm = x
        s.contraction = (big_l - x) / x if x > 0.0 else 0.0
        s.resistance_ohm = s.resistance0_ohm
        for apply in self._post:
            apply(s)
        if s.resistance_ohm < 0.0:
            s.resistance_ohm = 0.0
        length, resistance = s.length_mm, s.resistance_ohm
        if self._sensor:
            for apply in self._sensor:
                apply(s)
            length, resistance = s.length_mm, s.resistance_ohm
        return PlantReading(length, resistance)


def plant_from_config(plant_cfg: Mapping[str, Any], seed: int | None = None, fused: bool = True) -> TsaPlant:
    """Build the plant from a bench file's ``plant`` mapping; raise ValueError naming a bad key.

    ``seed`` overrides ``plant_cfg['seed']``; with neither, noise is not reproducible.
    ``fused`` False runs the effect chain on every sample (the reference; see :class:`TsaPlant`).
    Missing keys and effects take their documented defaults (every effect on except those
    with ``default_enabled`` False).
    """
    where = "plant"
    check_keys(plant_cfg, PLANT_KEYS, where)
    cfg_seed = plant_cfg.get("seed")   # checked even when ``seed`` overrides it: `validate` refuses what `run` would
    if cfg_seed is not None and (isinstance(cfg_seed, bool) or not isinstance(cfg_seed, int) or cfg_seed < 0):
        raise ValueError(f"{where}: 'seed' must be an integer >= 0 or null, got {cfg_seed!r}")
    if seed is None:
        seed = cfg_seed
    items = plant_cfg.get("effects")
    if items is None:
        items = {}
    if not isinstance(items, Mapping):
        raise ValueError("plant: 'effects' must be a mapping {effect name: {enabled: bool, parameter: value}}")
    unknown = sorted(set(items) - set(EFFECTS) - set(FORMS))
    if unknown:
        raise ValueError(f"plant.effects: unknown effect(s) {unknown} (known: {', '.join(canonical_order())}; "
                         f"alternative forms: {', '.join(FORMS)})")
    for name, cfg in items.items():
        parse_effect_config(name, cfg)  # validate everything, even switched-off effects
    rng = random.Random(seed)
    effects = []
    for name in canonical_order():
        sub = random.Random(rng.getrandbits(64))
        e = build_effect(name, items.get(name), sub)
        if e is not None:
            effects.append(e)
    # alternative forms run only when the config names them (their seeds follow the library's)
    for name in canonical_order([n for n in FORMS if n in items]):
        e = build_effect(name, items[name], random.Random(rng.getrandbits(64)))
        if e is not None:
            effects.append(e)
    return TsaPlant(
        untwisted_length_mm=number_param(plant_cfg, "untwisted_length_mm", where, 248.0, minimum=1e-9),
        radius_mm=number_param(plant_cfg, "radius_mm", where, 0.51, minimum=0.0),
        resistance_ohm=number_param(plant_cfg, "resistance_ohm", where, 5.0, minimum=0.0),
        ambient_C=number_param(plant_cfg, "ambient_C", where, 22.0),
        load_g=number_param(plant_cfg, "initial_load_g", where, 0.0, minimum=0.0),
        effects=effects,
        fused=fused,
    )
