"""The plant's mutable state, the :class:`Effect` base class and the effect registry.

Units: time in s, twist in motor turns (signed), heater voltage in V, load in g (force
in N where named ``_N``), length in mm, resistance in ohm, temperature in degC.

Contract: the plant owns one :class:`PlantState`. Each sample it writes the inputs
(``t_s``, ``dt_s``, ``turns_cmd``, ``heater_voltage_V``, ``motor_moving``, ``load_g``),
then runs the enabled effects stage by stage in the canonical order of :data:`STAGES`
(``motor -> thermal -> geometry -> kinematics -> length -> resistance -> sensor``;
the ``kinematics`` stage is the plant's own TSA model, not an effect). Within a stage
effects run in registration order. An effect reads and writes the state's slots in
place (``apply(state) -> None``) and keeps its own memory (play operators, creep,
transients) between calls; ``reset()`` forgets that memory. Every effect declares
``name``, ``stage``, ``source`` (thesis section / paper), ``default_enabled`` (on when a
bench file does not name it; True except for effects added after the presets, which a
bench file must switch on) and a ``Params`` dataclass whose fields carry
``metadata={"units": ..., "doc": ...}``; :func:`build_effect`
validates a config mapping against it and raises ``ValueError`` naming bad keys.

Every library effect and form also has a fused form in :mod:`tsa_bench.sim.fused` (the
same operations on the plant's locals, so a plant runs without a call per effect); its
``apply`` stays the reference the fused form must equal bit for bit
(``tests/sim/test_sim_fused.py`` runs every effect and form both ways). An effect without
a fused form (one registered by a user or a test) still works: its plant runs the chain of
``apply`` calls.
"""

from __future__ import annotations

import dataclasses
import math
import random
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

#: Canonical stage order. ``kinematics`` is computed by the plant between
#: ``geometry`` and ``length``.
STAGES = ("motor", "thermal", "geometry", "kinematics", "length", "resistance", "sensor")


@dataclass(slots=True)
class PlantState:
    """Everything the effects and the plant share at one sample (mutable)."""

    # -- constants of the plant (set at construction) --
    untwisted_length_mm: float = 248.0   # L0: unloaded, untwisted string length
    radius_mm: float = 0.51              # r0: untwisted TSA radius
    resistance0_ohm: float = 5.0         # R0: resistance at L0, untwisted, unloaded, ambient
    ambient_C: float = 22.0              # ambient temperature
    # -- inputs (written by the plant every sample) --
    t_s: float = 0.0
    dt_s: float = 0.0
    turns_cmd: float = 0.0               # twist the motor was told to make (step count)
    heater_voltage_V: float = 0.0
    motor_moving: bool = False
    load_g: float = 0.0
    load_N: float = 0.0
    # -- derived motion (motor stage, then the plant's bookkeeping) --
    turns: float = 0.0                   # actual motor twist (after missed steps)
    direction: int = 0                   # +1 |twist| increasing, -1 decreasing, 0 still
    t_since_stop_s: float = math.inf     # time since the motor last stopped (inf: never moved)
    travel_turns: float = 0.0            # cumulative |d turns| (wear)
    # -- thermal --
    temperature_C: float = 22.0
    # -- geometry --
    stiffness_factor: float = 1.0        # load_dependence: K_eff = K * factor
    hysteresis_scale: float = 1.0        # load_dependence: scales hysteresis terms
    turns_eff: float = 0.0               # twist seen by the kinematics (after twist hysteresis)
    string_length_mm: float = 248.0      # L: stretched (and thermally contracted) string length
    radius_growth: bool = False          # True: r = r0 sqrt(L0 / X); False: r = r0
    # -- kinematics / length --
    kinematic_length_mm: float = 248.0   # X from the TSA model, before length effects
    contraction: float = 0.0             # (L - X) / X of the previous sample
    length_mm: float = 248.0             # TSA length the position sensor sees
    # -- resistance --
    resistance_ohm: float = 5.0


def param(default: float, units: str, doc: str, minimum: float | None = None, maximum: float | None = None) -> Any:
    """A ``Params`` field with its units, one-line doc and optional bounds."""
    return field(default=default, metadata={"units": units, "doc": doc, "minimum": minimum, "maximum": maximum})


@dataclass(frozen=True)
class NoParams:
    """An effect without parameters."""


class Effect:
    """One named, switchable physical effect (see module docstring)."""

    name: ClassVar[str] = ""
    stage: ClassVar[str] = ""
    source: ClassVar[str] = ""
    Params: ClassVar[type] = NoParams
    #: whether a bench file that does not name the effect gets it; effects added to the
    #: library later are off by default, so that no existing bench file changes behaviour
    default_enabled: ClassVar[bool] = True

    def __init__(self, params: Any = None, rng: random.Random | None = None) -> None:
        self.params = params if params is not None else self.Params()
        self.rng = rng if rng is not None else random.Random(0)
        self.reset()

    def reset(self) -> None:
        """Forget all memory (operators, creep, transients)."""

    def apply(self, state: PlantState) -> None:  # pragma: no cover - abstract
        raise NotImplementedError


#: Effect name -> Effect subclass, in registration order.
EFFECTS: dict[str, type[Effect]] = {}


def register_effect(cls_or_name: Any = None) -> Any:
    """Class decorator registering an :class:`Effect` subclass under ``cls.name``.

    ``@register_effect`` and ``@register_effect("name")`` both work; names are unique
    and the stage must be one of :data:`STAGES` (not ``kinematics``).
    """
    def deco(cls: type[Effect]) -> type[Effect]:
        if isinstance(cls_or_name, str):
            cls.name = cls_or_name
        if not cls.name:
            raise ValueError(f"{cls.__name__}: an effect needs a name")
        if cls.name in EFFECTS:
            raise ValueError(f"plant effect '{cls.name}' is already registered")
        if cls.stage not in STAGES or cls.stage == "kinematics":
            raise ValueError(f"plant effect '{cls.name}': unknown stage {cls.stage!r}")
        EFFECTS[cls.name] = cls
        return cls
    if isinstance(cls_or_name, type):
        return deco(cls_or_name)
    return deco


#: Alternative physical forms of library effects (name -> class), e.g. missed steps whose
#: pull-out torque falls with speed. A form is off unless a plant config names it; it
#: runs in its stage after the library effects. ``cls.form_of`` names the effect it is a
#: form of and ``cls.form`` the form (see :mod:`tsa_bench.sim.effects.forms_motor` etc.).
FORMS: dict[str, type[Effect]] = {}


def register_form(cls: type[Effect]) -> type[Effect]:
    """Class decorator registering an alternative form (needs ``name``, ``stage``, ``form_of``, ``form``)."""
    if not cls.name or cls.name in EFFECTS or cls.name in FORMS:
        raise ValueError(f"{cls.__name__}: a form needs a new, unique name (got {cls.name!r})")
    if cls.stage not in STAGES or cls.stage == "kinematics":
        raise ValueError(f"plant effect form '{cls.name}': unknown stage {cls.stage!r}")
    if getattr(cls, "form_of", None) not in EFFECTS or not getattr(cls, "form", ""):
        raise ValueError(f"plant effect form '{cls.name}': form_of must name a library effect, and form be set")
    FORMS[cls.name] = cls
    return cls


def effect_class(name: str) -> type[Effect] | None:
    """The class of a library effect or of an alternative form, or None."""
    return EFFECTS.get(name) or FORMS.get(name)


def canonical_order(names: list[str] | tuple[str, ...] | None = None) -> list[str]:
    """Effect names (all registered library effects, or ``names``, which may include
    forms) in stage, then registration, order (forms after the library effects)."""
    registered = list(EFFECTS) + list(FORMS)
    chosen = list(EFFECTS) if names is None else [n for n in registered if n in set(names)]
    return sorted(chosen, key=lambda n: (STAGES.index(effect_class(n).stage), registered.index(n)))


def number_param(params: Mapping[str, Any], key: str, where: str, default: float | None = None,
                 minimum: float | None = None, maximum: float | None = None) -> float:
    """Read a numeric parameter; raise ValueError naming ``where`` and ``key``."""
    if key not in params:
        if default is None:
            raise ValueError(f"{where}: missing required key '{key}'")
        return default
    value = params[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value:
        raise ValueError(f"{where}: '{key}' must be a number, got {value!r}")
    if minimum is not None and value < minimum:
        raise ValueError(f"{where}: '{key}' must be >= {minimum}, got {value}")
    if maximum is not None and value > maximum:
        raise ValueError(f"{where}: '{key}' must be <= {maximum}, got {value}")
    return float(value)


def check_keys(params: Mapping[str, Any], allowed: tuple[str, ...], where: str) -> None:
    """Refuse unknown keys, naming them and the allowed ones."""
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown} (allowed: {', '.join(allowed)})")


def parse_effect_config(name: str, cfg: Any) -> tuple[bool, Any]:
    """``(enabled, Params)`` from one ``plant.effects.<name>`` mapping (None = defaults)."""
    where = f"plant.effects.{name}"
    cls = effect_class(name)
    if cls is None:
        raise ValueError(f"plant.effects: unknown effect '{name}' (known: {', '.join(canonical_order())})")
    if cfg is None:
        cfg = {}
    if isinstance(cfg, bool):
        cfg = {"enabled": cfg}
    if not isinstance(cfg, Mapping):
        raise ValueError(f"{where}: must be a mapping (enabled: bool, parameters), got {cfg!r}")
    fields = {f.name: f for f in dataclasses.fields(cls.Params)}
    check_keys(cfg, ("enabled", *fields), where)
    enabled = cfg.get("enabled", cls.default_enabled)
    if not isinstance(enabled, bool):
        raise ValueError(f"{where}: 'enabled' must be true or false, got {enabled!r}")
    values = {}
    for key, f in fields.items():
        if key in cfg:
            default = f.default
            if isinstance(default, bool):
                if not isinstance(cfg[key], bool):
                    raise ValueError(f"{where}: '{key}' must be true or false, got {cfg[key]!r}")
                values[key] = cfg[key]
            else:
                values[key] = number_param(cfg, key, where, minimum=f.metadata.get("minimum"),
                                           maximum=f.metadata.get("maximum"))
    return enabled, cls.Params(**values)


def build_effect(name: str, cfg: Any, rng: random.Random) -> Effect | None:
    """The configured effect, or None if it is switched off."""
    enabled, params = parse_effect_config(name, cfg)
    return effect_class(name)(params, rng) if enabled else None


def describe_effect(cls: type[Effect]) -> dict[str, Any]:
    """Name, stage, source, first doc line and parameters (units, default, doc) of one effect."""
    doc = (cls.__doc__ or "").strip().splitlines()
    return {
        "name": cls.name,
        "stage": cls.stage,
        "source": cls.source,
        "default_enabled": cls.default_enabled,
        "doc": doc[0] if doc else "",
        "params": [{"name": f.name, "units": f.metadata.get("units", ""), "default": f.default,
                    "doc": f.metadata.get("doc", "")} for f in dataclasses.fields(cls.Params)],
    }

