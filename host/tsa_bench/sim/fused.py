"""The plant's sample loop fused into one generated function per plant layout.

Units: as :mod:`tsa_bench.sim.plant` (s, turns, V, g/N, mm, ohm, degC).

Contract: :func:`fuse` turns a :class:`~tsa_bench.sim.plant.TsaPlant` whose effects are
all library effects or forms (their exact classes) into a :class:`Kernel`: closures that
do what the plant's per-effect ``apply`` chain does, with the same floating-point
operations in the same order and the same random draws, so that the readings are
bit-identical to the chain's (``tests/sim/test_sim_fused.py`` checks every effect and
form against the chain; each effect's part of the code is in
:mod:`tsa_bench.sim.fused_effects`). The state the effects share lives in the closures' cells
while the kernel runs; ``Kernel.export`` writes it back to the plant's
:class:`~tsa_bench.sim.effects.PlantState`, the effects' memory and the plant. An
effect whose parameters make it a no-op (``twist_stiffening`` with ``per_turn`` 0,
``thermal_softening`` with ``per_K`` 0, ``thermal_actuation`` or ``thermal_contraction``
with ``strain_per_K`` 0, sensor noise or quantisation of a channel at 0) emits no code; a
settling effect without hold draws adds its constant offset. Quantities that change only
with the load are computed in ``set_load``; the missed-steps load torque is computed only
when a bound on it (with a margin far above rounding) reaches the holding torque; a
kinematics evaluation with the inputs of the last one, the play operators of the
resistance hysteresis at the length and thresholds of the last sample (nothing moves) and
an exponential decay factor at the last step and time constant reuse the last result.
The generated source depends on the plant's
layout (which effects, which no-ops), not on parameter values, and is compiled once
per layout. Any other effect (a custom ``register_effect``) makes :func:`fuse` return
None and the plant runs its chain.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple

from tsa_bench.sim.effects import EFFECTS, FORMS, effect_class
from tsa_bench.sim.fused_effects import SNIPPETS, Snip, length_expr
from tsa_bench.sim.readings import PlantReading

if TYPE_CHECKING:  # pragma: no cover
    from tsa_bench.sim.plant import TsaPlant

_SQRT3 = math.sqrt(3.0)

#: the generated code's globals (its constants are computed exactly as the effects compute them)
_GLOBALS: dict[str, Any] = {
    "exp": math.exp, "log": math.log, "sqrt": math.sqrt, "cos": math.cos, "sin": math.sin, "acos": math.acos,
    "tanh": math.tanh, "inf": math.inf, "TWO_PI": 2.0 * math.pi, "SQRT3": _SQRT3, "NEG15S3": -1.5 * _SQRT3,
    "TWO_S3": 2.0 / _SQRT3, "GAUSS_TWOPI": 2.0 * math.pi, "PlantReading": PlantReading, "_make": tuple.__new__,
}

class Kernel(NamedTuple):
    """A fused plant: ``sample(t_s, turns, heater_V, moving) -> PlantReading``,
    ``block(ts, turns, volts, moving, out_length, out_resistance, out_temperature, out_turns)``
    (appends to the lists; the last two may be None; None when built without it),
    ``set_load(load_g, load_N)``, ``export()``."""

    sample: Callable[..., PlantReading]
    block: Callable[..., None]
    set_load: Callable[[float, float], None]
    export: Callable[[], None]


#: the plant's own per-sample quantities (PlantState slot or plant attribute they export to)
_PLANT_CELLS = (("t_prev", "plant._t_prev"), ("moving_prev", "plant._moving_prev"), ("dt", "st.dt_s"),
                ("cmd_last", "st.turns_cmd"), ("volts_last", "st.heater_voltage_V"), ("turns", "st.turns"),
                ("travel", "st.travel_turns"), ("since", "st.t_since_stop_s"),
                ("T", "st.temperature_C"), ("kf", "st.stiffness_factor"), ("hs", "st.hysteresis_scale"),
                ("te", "st.turns_eff"), ("L", "st.string_length_mm"), ("rg", "st.radius_growth"),
                ("X", "st.kinematic_length_mm"), ("contraction", "st.contraction"), ("x", "st.length_mm"),
                ("R", "st.resistance_ohm"), ("load_g", "st.load_g"), ("load_N", "st.load_N"))

_PROLOGUE = """\
tp = t_prev
if tp is None or t_s < tp:
    dt = 0.0
else:
    dt = t_s - tp
t_prev = t_s
cmd_last = turns_cmd
volts_last = volts
moving = motor_moving is True or (motor_moving is not False and bool(motor_moving))
prev_turns = turns
turns = turns_cmd"""

_BOOKKEEPING = """\
travel += abs(turns - prev_turns) if tp is not None else abs(turns)
if moving or moving_prev:
    since = 0.0
else:
    since += dt
moving_prev = moving
te = turns
L = L0
rg = False
kf = 1.0
hs = 1.0"""


def _source(plant: TsaPlant, block: bool = False) -> tuple[str, list[Snip]] | None:
    """The factory's source for this plant's layout, or None if an effect cannot be fused."""
    snips: list[Snip] = []
    stages: dict[str, list[str]] = {}
    for i, e in enumerate(plant._effects):
        make = SNIPPETS.get(e.name)
        if make is None or effect_class(e.name) is not type(e) or (e.name not in EFFECTS and e.name not in FORMS):
            return None
        s = Snip()
        s.E = f"E[{i}]"
        make(s, e, f"e{i}_", s.E)
        snips.append(s)
        stages.setdefault(e.stage, []).extend(s.body)
    growth = any(e.name == "radius_growth" for e in plant._effects)
    body = _PROLOGUE.splitlines() + stages.get("motor", []) + _BOOKKEEPING.splitlines()
    body += stages.get("thermal", []) + stages.get("geometry", [])
    body += ["if L == km_L and te == km_te:", "    x = km_x", "else:"]
    length_expr(body, "x", "L", "te", growth, "    ")
    body += ["    km_L = L", "    km_te = te", "    km_x = x",
             "X = x", "contraction = (L - x) / x if x > 0.0 else 0.0", "R = R0"]
    body += stages.get("length", []) + stages.get("resistance", [])
    body += ["if R < 0.0:", "    R = 0.0"] + stages.get("sensor", [])

    cells = [c for c, _ in _PLANT_CELLS] + ["prev_turns", "km_L", "km_te", "km_x"]
    for s in snips:
        cells += [v for v, _ in s.memory] + [v for v, _ in s.cells] + s.perload_vars
    nonlocal_line = "nonlocal " + ", ".join(cells)

    src = ["def factory(plant, st, E):",
           "    L0 = st.untwisted_length_mm", "    r0 = st.radius_mm", "    R0 = st.resistance0_ohm",
           "    amb = st.ambient_C"]
    src += [f"    {v} = {where}" for v, where in _PLANT_CELLS]
    src += ["    prev_turns = None  # the twist before the last sample: the direction is worked out on export",
            "    km_L = km_te = km_x = None"]
    for s in snips:
        src += [f"    {v} = {expr}" for v, expr in s.params]
        src += [f"    {v} = {s.E}.{attr}" for v, attr in s.memory]
        src += [f"    {v} = {expr}" for v, expr in s.cells if expr is not None]
        src += ["    " + line for line in s.load_lines]
    perload = [line for s in snips for line in s.perload]
    perload_vars = [v for s in snips for v in s.perload_vars]
    src += ["    " + line for line in perload]
    bound = ["tqb_rg = TWO_PI * load_N * r0 * r0 * L0 * 3.0 * 1e-3 * (1.0 + 1e-6)",
             "tqb_plain = TWO_PI * load_N * r0 * r0 * SQRT3 * 1e-3 * (1.0 + 1e-6)"]
    src += ["    " + line for line in bound]
    src += ["    def set_load(g, n):",
            "        nonlocal " + ", ".join(["load_g", "load_N", "tqb_rg", "tqb_plain"] + perload_vars),
            "        load_g = g", "        load_N = n"]
    src += ["        " + line for line in bound + perload]
    torque = ["    def torque(tn):",
              "        theta = TWO_PI * abs(tn)",
              "        if theta == 0.0:",
              "            return 0.0"]
    length_expr(torque, "xx", "L", "tn", "rg", "        ")
    torque += ["        r2 = r0 * r0 * (L0 / xx if rg else 1.0)",
               "        return load_N * theta * r2 / xx * 1e-3"]
    src += torque
    src += ["    def sample(t_s, turns_cmd, volts, motor_moving):", "        " + nonlocal_line]
    src += ["        " + line for line in body]
    src += ["        return _make(PlantReading, (x, R))"]
    if block:
        src += ["    def block(ts, cmds, vs, ms, out_l, out_r, out_t, out_a):", "        " + nonlocal_line,
                "        add_l = out_l.append", "        add_r = out_r.append",
                "        for t_s, turns_cmd, volts, motor_moving in zip(ts, cmds, vs, ms):"]
        src += ["            " + line for line in body]
        src += ["            add_l(x)", "            add_r(R)",
                "            if out_t is not None:", "                out_t.append(T)",
                "            if out_a is not None:", "                out_a.append(turns)"]
    else:
        src += ["    block = None"]
    src += ["    def export():"]
    src += [f"        {where} = {v}" for v, where in _PLANT_CELLS]
    src += ["        if t_prev is not None:", "            st.t_s = t_prev", "            st.motor_moving = moving_prev",
            "        if prev_turns is not None:",
            "            d = abs(turns) - abs(prev_turns)",
            "            st.direction = 1 if d > 0.0 else -1 if d < 0.0 else 0"]
    for s in snips:
        src += [f"        {s.E}.{attr} = {v}" for v, attr in s.memory]
        src += ["        " + line for line in s.export_lines]
    src += ["        return None", "    return sample, block, set_load, export"]
    return "\n".join(src), snips


_COMPILED: dict[str, Callable[..., tuple]] = {}


def fuse(plant: TsaPlant, block: bool = False) -> Kernel | None:
    """The plant's fused kernel, started from its present state (module docstring), or None.
    Without ``block`` the kernel has no block loop (``Kernel.block`` None; half the code to compile)."""
    made = _source(plant, block)
    if made is None:
        return None
    text, _ = made
    factory = _COMPILED.get(text)
    if factory is None:
        namespace = dict(_GLOBALS)
        exec(compile(text, "<tsa_bench.sim.fused>", "exec"), namespace)  # noqa: S102 - our own generated code
        factory = _COMPILED[text] = namespace["factory"]
    return Kernel(*factory(plant, plant._state, plant._effects))
