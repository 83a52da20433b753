"""The candidate causes: library effects, each in one or more physical forms.

Units: every bound in the parameter's own units (``tsa-bench effects``).

Contract: :data:`FAMILIES` maps an effect (the name diagnose reports) to its forms
(plant effect or alternative form name -> human form label). :data:`FORM_SPECS` holds
the parameters freed when a form is switched on, with search ranges wide enough for
any plausible string and physical limits marked ``hard``; a fitted value at a soft
bound means the form does not describe the data. :func:`screen_params` gives a few
parameter sets per form (scaled to the run: twist reached, load torque, duration) whose
signatures screen the form. :data:`NEEDS` names the excitation a family needs to be
testable at all (a load dependence cannot be told apart on a constant load).
"""

from __future__ import annotations

from dataclasses import dataclass

from tsa_bench.analysis.paramspec import ParamSpec

#: effect -> {plant effect/form name: form label}; the first form is the library's own.
FAMILIES: dict[str, dict[str, str]] = {
    "missed_steps": {"missed_steps": "torque-limited static", "missed_steps_pullout": "speed-dependent pull-out",
                     "missed_steps_saturating": "saturating above a twist"},
    "thermal_dynamics": {"thermal_dynamics": "first-order heating, slow cooling"},
    "load_dependence": {"load_dependence": "stiffness softening with contraction"},
    "twist_hysteresis": {"twist_hysteresis": "play operator on twist"},
    "length_creep": {"length_creep": "after load changes", "length_creep_twist": "after twist changes"},
    "resistance_hysteresis": {"resistance_hysteresis": "rate-dependent Prandtl-Ishlinskii"},
    "resistance_transient_decay": {"resistance_transient_decay": "thesis ln^2 law",
                                   "resistance_transient_stretched": "stretched exponential",
                                   "resistance_transient_two_exp": "sum of exponentials"},
    "resistance_creep": {"resistance_creep": "with twist travel (cycles)", "resistance_creep_time": "with time"},
    "resistance_temperature": {"resistance_temperature": "temperature coefficient"},
    "length_sensor_drift": {"length_offset_drift": "offset drift with time", "length_gain_drift": "gain drift with time"},
    "resistance_sensor_drift": {"resistance_offset_drift": "offset drift with time",
                                "resistance_gain_drift": "gain drift with time"},
}
#: plant effect/form name -> effect (family) name
FAMILY_OF = {form: fam for fam, forms in FAMILIES.items() for form in forms}
#: the outputs each family acts on directly (length effects move the resistance too, through dR/dX)
OUTPUT_OF = {"missed_steps": "length", "thermal_dynamics": "length", "load_dependence": "length",
             "twist_hysteresis": "length", "length_creep": "length", "resistance_hysteresis": "resistance",
             "resistance_transient_decay": "resistance", "resistance_creep": "resistance",
             "resistance_temperature": "resistance", "length_sensor_drift": "length",
             "resistance_sensor_drift": "resistance"}
#: families that act on one sensor's reading only (a length sensor's drift does not move the resistance)
READING_ONLY = frozenset({"length_sensor_drift", "resistance_sensor_drift"})
#: excitation (holdout kinds) a family needs: any of these must occur in the runs
NEEDS = {"thermal_dynamics": ("heater_on",), "resistance_temperature": ("heater_on",),
         "load_dependence": ("load_change",), "resistance_transient_decay": ("hold",),
         "twist_hysteresis": ("twist_up",), "resistance_hysteresis": ("twist_up",),
         "missed_steps": ("twist_up",), "length_creep": ("hold",), "resistance_creep": ("hold", "twist_up"),
         "length_sensor_drift": ("hold",), "resistance_sensor_drift": ("hold",)}


def _s(key, lo, hi, log=False, hard_lo=False, hard_hi=False):
    return ParamSpec(key, lo, hi, log, hard_lo, hard_hi)


FORM_SPECS: dict[str, tuple[ParamSpec, ...]] = {
    "missed_steps": (_s("missed_steps.holding_torque_Nm", 1e-6, 2.0, True),),
    "missed_steps_pullout": (_s("missed_steps_pullout.pullout_torque_Nm", 1e-6, 2.0, True),
                             _s("missed_steps_pullout.corner_speed_turns_per_s", 0.02, 100.0, True),
                             _s("missed_steps_pullout.slip_exponent", 0.3, 100.0, True, hard_hi=True)),
    "missed_steps_saturating": (_s("missed_steps_saturating.threshold_turns", 0.0, 400.0, hard_lo=True),
                                _s("missed_steps_saturating.slip_fraction", 0.0, 1.0, hard_lo=True, hard_hi=True)),
    "thermal_dynamics": (_s("thermal_dynamics.thermal_resistance_K_per_W", 0.1, 200.0, True),
                         _s("thermal_dynamics.heat_capacity_J_per_K", 0.005, 20.0, True),
                         _s("thermal_dynamics.cooling_time_constant_s", 0.5, 2000.0, True)),
    "load_dependence": (_s("load_dependence.stiffness_softening", 0.0, 4.0, hard_lo=True),),
    "twist_hysteresis": (_s("twist_hysteresis.play_turns", 0.0, 10.0, hard_lo=True),),
    "length_creep": (_s("length_creep.strain_per_N", 0.0, 0.05, hard_lo=True),
                     _s("length_creep.time_constant_s", 2.0, 3000.0, True)),
    "length_creep_twist": (_s("length_creep_twist.creep_fraction", 0.0, 0.8, hard_lo=True),
                           _s("length_creep_twist.time_constant_s", 0.5, 1500.0, True)),
    "resistance_hysteresis": (_s("resistance_hysteresis.ohm_per_mm", 0.0, 0.5, hard_lo=True),
                              _s("resistance_hysteresis.alpha_mm", 0.02, 20.0, True)),
    "resistance_transient_decay": (_s("resistance_transient_decay.b1_ohm", -0.05, 0.0, hard_hi=True),
                                   _s("resistance_transient_decay.b2_ohm", -0.6, 0.0, hard_hi=True)),
    "resistance_transient_stretched": (_s("resistance_transient_stretched.amp_ohm", -1.0, 1.0),
                                       _s("resistance_transient_stretched.time_constant_s", 0.05, 1000.0, True),
                                       _s("resistance_transient_stretched.beta", 0.15, 1.0, hard_hi=True)),
    "resistance_transient_two_exp": (_s("resistance_transient_two_exp.a1_ohm", -1.0, 1.0),
                                     _s("resistance_transient_two_exp.tau1_s", 0.05, 30.0, True),
                                     _s("resistance_transient_two_exp.a2_ohm", -1.0, 1.0),
                                     _s("resistance_transient_two_exp.tau2_s", 3.0, 2000.0, True)),
    "resistance_creep": (_s("resistance_creep.ohm_per_turn", -2e-3, 2e-3),),
    "resistance_creep_time": (_s("resistance_creep_time.ohm_per_hour", -5.0, 5.0),
                              _s("resistance_creep_time.time_constant_s", 30.0, 1e6, True)),
    "resistance_temperature": (_s("resistance_temperature.alpha_per_K", -0.01, 0.01),),
    "length_offset_drift": (_s("length_offset_drift.mm_per_hour", -50.0, 50.0),),
    "length_gain_drift": (_s("length_gain_drift.per_hour", -0.2, 0.2),),
    "resistance_offset_drift": (_s("resistance_offset_drift.ohm_per_hour", -5.0, 5.0),),
    "resistance_gain_drift": (_s("resistance_gain_drift.per_hour", -0.2, 0.2),),
}


@dataclass
class RunScale:
    """What screening variants are scaled to: the run's reach."""

    max_turns: float            # largest |twist| commanded
    max_torque_Nm: float        # largest load torque the calibrated model predicts
    max_speed_turns_per_s: float
    typical_speed_turns_per_s: float   # median commanded speed while moving
    duration_s: float
    resistance_ohm: float       # typical resistance level
    resistance_noise_ohm: float
    length_mm: float = 250.0    # typical length
    length_noise_mm: float = 0.05


def screen_params(form: str, sc: RunScale) -> list[dict[str, float]]:
    """Parameter sets whose signatures screen ``form`` on a run of scale ``sc``."""
    tq, tw, rn = max(sc.max_torque_Nm, 1e-9), max(sc.max_turns, 1.0), max(sc.resistance_noise_ohm, 1e-6)
    amp = 20.0 * rn
    if form == "missed_steps":
        return [{"holding_torque_Nm": tq * q} for q in (0.5, 0.7, 0.85, 0.95)]
    if form == "missed_steps_pullout":
        w = max(sc.typical_speed_turns_per_s, 0.1)
        return [{"pullout_torque_Nm": tq * q * (1 + w / wc), "corner_speed_turns_per_s": wc, "slip_exponent": n}
                for q in (0.5, 0.8) for wc in (0.5 * w, 2.0 * w) for n in (2.0, 20.0)]
    if form == "missed_steps_saturating":
        return [{"threshold_turns": tw * q, "slip_fraction": 0.3} for q in (0.4, 0.6, 0.8)]
    if form == "thermal_dynamics":
        return [{}, {"cooling_time_constant_s": 8.0}, {"cooling_time_constant_s": 100.0}]
    if form == "load_dependence":
        return [{"stiffness_softening": 0.5}]
    if form == "twist_hysteresis":
        return [{"play_turns": 0.3}, {"play_turns": 1.0}]
    if form == "length_creep":
        return [{"strain_per_N": 1e-3, "time_constant_s": t} for t in (40.0, 180.0, 700.0)]
    if form == "length_creep_twist":
        return [{"creep_fraction": 0.1, "time_constant_s": t} for t in (5.0, 30.0, 150.0)]
    if form == "resistance_hysteresis":
        return [{"ohm_per_mm": 0.015, "alpha_mm": a} for a in (1.0, 3.0)]
    if form == "resistance_transient_decay":
        return [{"b1_ohm": -1.71e-3, "b2_ohm": -2.68e-2}]
    if form == "resistance_transient_stretched":
        return [{"amp_ohm": amp, "time_constant_s": t, "beta": 0.6} for t in (3.0, 15.0, 60.0)]
    if form == "resistance_transient_two_exp":
        return [{"a1_ohm": amp, "tau1_s": 1.5, "a2_ohm": amp, "tau2_s": t} for t in (20.0, 80.0)]
    if form == "resistance_creep":
        return [{"ohm_per_turn": 1e-5}]
    if form == "resistance_creep_time":
        return [{"ohm_per_hour": amp, "time_constant_s": t} for t in (0.5 * sc.duration_s, 1e5)]
    if form == "resistance_temperature":
        return [{"alpha_per_K": 5e-4}]
    hours = max(sc.duration_s, 1.0) / 3600.0     # drifts reaching 20 noise RMS by the end of the run
    ln = max(sc.length_noise_mm, 1e-6)
    if form == "length_offset_drift":
        return [{"mm_per_hour": 20.0 * ln / hours}]
    if form == "length_gain_drift":
        return [{"per_hour": 20.0 * ln / hours / max(sc.length_mm, 1.0)}]
    if form == "resistance_offset_drift":
        return [{"ohm_per_hour": amp / hours}]
    if form == "resistance_gain_drift":
        return [{"per_hour": amp / hours / max(sc.resistance_ohm, 1e-3)}]
    return [{}]
