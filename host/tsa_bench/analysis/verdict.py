"""From the numbers to the verdict: explained, named, unexplained or model_mismatch.

Units: structured RMS in the output's units; improvements in noise variances per sample.

Contract (the decision rule; docs/diagnose.md explains it):

* ``model_mismatch`` when a needed input is missing, when a parameter of the final model
  ended at a soft bound of its search range (the data want a value outside what the
  model covers), or when the final model misses more than half of an output's variation
  above the noise (``R^2`` over the noise-free variance < :data:`R2_MIN`);
* ``named`` when at least one cause passed the naming gate (diagnose.py) *and*, on the
  output it acts on, the final model removed at least :data:`SHARE_MIN` of the judged
  model's structured variance; a named cause whose output is still structured keeps a
  caveat saying what the residual still follows, and its confidence is multiplied by
  that share. A cause that removes less is demoted to ``partial`` (reported, not named),
  as is one whose own part in the final model (that model re-calibrated without it) has a
  95 % interval of its held-out improvement reaching zero or below;
* ``unexplained`` when nothing is named but some output's residual is structured
  (structure.py), saying what it follows;
* ``explained`` otherwise: every judged output's residual is consistent with the noise
  model (no significant structure above the relevance floor).
"""

from __future__ import annotations

from dataclasses import dataclass

from tsa_bench.analysis.signals import DESCRIBE

R2_MIN = 0.5
SHARE_MIN = 0.5


@dataclass
class OutputState:
    """What the engine learnt about one output."""

    before: dict          # structure_test of the judged model (+ follows, jumps)
    after: dict           # structure_test of the final model (+ follows, jumps)
    r2_noise_free: float | None
    units: str


def share_removed(st: OutputState) -> float:
    """Share of the judged model's structured variance the final model removed (1 if none)."""
    b, a = st.before.get("structured_rms") or 0.0, st.after.get("structured_rms") or 0.0
    if not st.before.get("structured") or b <= 0:
        return 1.0
    return max(0.0, 1.0 - (a * a) / (b * b))


def percent(x: float) -> str:
    """A share as text; never "100 %" for less than all of it."""
    return "over 99 %" if 0.99 < x < 1.0 else f"{100 * x:.0f} %"


def follows_text(out: str, test: dict) -> str:
    def said(signal: str) -> str:
        if signal == "length" and test.get("undriven"):   # no scale error to blame: nothing drives the model
            return ("the measured length (no input of the model drives the actuator on these runs: the motion "
                    "itself is unexplained)")
        return DESCRIBE.get(signal, signal)

    parts = [f"{said(f['signal'])} ({100 * f['share']:.0f} % of its structure)" for f in test.get("follows", [])[:3]]
    if parts:
        return f"{out} residual follows " + ", ".join(parts)
    if test.get("jumps", 0) >= 3:
        return f"{out} residual jumps ({test['jumps']} abrupt level changes away from motor moves) and follows none " \
               "of the inputs"
    return f"{out} residual is structured but follows none of the inputs"


def unexplained_entry(out: str, st: OutputState, induced: bool = False, near: list[dict] | None = None) -> dict:
    """What an output's residual still follows; the near misses (candidates that explain part of it,
    :mod:`tsa_bench.analysis.near`) are said before "not among the candidates"."""
    t = st.after
    near = near or []
    text = follows_text(out, t)
    if near:
        text += "; near misses: " + ", ".join(
            f"{n['effect']} ({n['form']}) would explain about {percent(n['share'])} of it (not named: {n['why_not']})"
            for n in near)
    text += ": not among the candidates"
    if induced:
        text = (f"{out} residual is structured only through the joint fit with the other output (calibrated on the "
                f"{out} alone it is noise)")
    return {"output": out, "structured_rms": t.get("structured_rms"), "units": st.units, "p": t.get("p"),
            "follows": t.get("follows", []), "jumps": t.get("jumps", 0), "induced": induced, "near_misses": near,
            "text": text}


def mismatch_entries(missing: list[tuple[str, str]], at_bound: list[dict], states: dict[str, OutputState]
                     ) -> list[dict]:
    out = [{"reason": p, "remedy": r} for p, r in missing]
    for b in at_bound:
        out.append({"reason": f"calibration: {b['key']} ended at the {b['side']} bound of its range "
                              f"({b['bound']:.4g}); the data want a value the model does not cover",
                    "remedy": "check the rig (units, sensor calibration) or judge a model that fits it (--model)"})
    for o, st in states.items():
        if st.r2_noise_free is not None and st.r2_noise_free < R2_MIN:
            out.append({"reason": f"the calibrated model misses {100 * (1 - max(st.r2_noise_free, 0)):.0f} % of the "
                                  f"{o} variation above the noise (held-out)",
                        "remedy": "judge a model that has the physics of this rig (--model BENCH.yaml), or check the "
                                  f"{o} column's units and calibration"})
    return out


def summary_line(verdict: str, named: list, unexplained: list[dict], mismatch: list[dict],
                 states: dict[str, OutputState]) -> str:
    if verdict == "model_mismatch":
        return "model_mismatch: " + mismatch[0]["reason"] + (f" (+{len(mismatch) - 1} more)" if len(mismatch) > 1
                                                               else "")
    if verdict == "named":
        parts = [f"{c.effect} ({c.form}, confidence {c.confidence:.2f})" for c in named]
        tail = f"; {unexplained[0]['text']}" if unexplained else ""
        return "named: " + ", then ".join(parts) + tail
    if verdict == "unexplained":
        return "unexplained: " + unexplained[0]["text"]
    shown = []
    for o, st in states.items():
        rms = st.after.get("rms")
        if rms is not None:
            shown.append(f"{o} {rms:.3g} {st.units}")
    return "explained: the calibrated model leaves only sensor noise (residual RMS " + ", ".join(shown) + ")"
