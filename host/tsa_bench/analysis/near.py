"""Near misses: candidates that explain part of what is left, reported before "not among the candidates".

Units: shares are fractions of an output's structured variance in the final model.

Contract: :func:`near_misses` looks at the last iteration of the search (the one that
started from the final model, or the latest one) and, for each output still structured,
lists the refitted candidates that were not named but improved that output's held-out
error (95 % interval above 0): effect, form, the share of the output's structured
variance their held-out improvement amounts to (at most 1), their held-out improvement
in noise variances per sample with its interval, and why the gate turned them down.
"""

from __future__ import annotations

from tsa_bench.analysis.context import Context
from tsa_bench.analysis.families import FAMILIES, FAMILY_OF
from tsa_bench.analysis.search import SearchResult

MAX_LISTED = 3


def near_misses(ctx: Context, found: SearchResult, states: dict) -> dict[str, list[dict]]:
    """Per structured output: up to :data:`MAX_LISTED` near misses, most explaining first."""
    named = {c.form for c in found.chosen}
    out: dict[str, list[dict]] = {}
    if not found.iterations:
        return out
    refits = found.iterations[-1].get("refit", {})
    for o, st in states.items():
        srms = st.after.get("structured_rms") or 0.0
        if not st.after.get("structured") or srms <= 0:
            continue
        structured = (srms / ctx.sigma[o]) ** 2      # noise variances per sample
        rows = []
        for key, r in refits.items():
            variant = key.split("+")[0]
            if variant in named or r.get("passed"):
                continue
            h = r["heldout"]
            imp, lo = h["improvement_noise_var"].get(o, 0.0), h["ci95"].get(o, [0.0, 0.0])[0]
            if imp <= 0 or lo <= 0:
                continue
            fam = FAMILY_OF[variant]
            rows.append({"effect": fam, "form": FAMILIES[fam][variant], "variant": variant,
                         "share": min(1.0, imp / structured), "improvement_noise_var": imp,
                         "ci95": list(h["ci95"][o]), "why_not": r.get("reason", "")})
        rows.sort(key=lambda d: -d["share"])
        out[o] = rows[:MAX_LISTED]
    return out
