"""Which samples are held out, and the resampling units of the held-out part.

Units: time in s.

Contract: :func:`split` sets each run's ``heldout`` mask and returns a
:class:`Holdout`. The default (SPEC None) keeps every kind of excitation on both sides:
each run is cut at segment boundaries into contiguous blocks of similar duration (one per
30 s, 10 to 24 of them: enough held-out blocks for the block bootstrap to have power), and
the held-out blocks (about 30 % of the time, never the first block, which
holds the start-up state) are the combination that leaves no kind of excitation (twist
up, twist down, holds, heater steps, heater on, load changes; kinds seen at least twice)
on one side only, with each kind's held-out share closest to 30 %; moves that reach the top
fifth of the run's twist count as a kind of their own (slip and saturation live there). With several runs the
whole last run is held out when it has the same kinds as the others. ``run:N``,
``after:SECONDS`` and ``fraction:F`` override (a suffix, or a whole run). The engine
replays every run whole (inputs are known everywhere); only the outputs of held-out
samples are never used to fit. :func:`units` cuts the held-out part into contiguous
resampling units at segment boundaries for the block bootstrap.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tsa_bench.analysis.inputs import RunInputs

KINDS = ("twist_up", "twist_down", "twist_peak", "hold", "heater_step", "heater_on", "load_change")
TARGET_FRACTION = 0.3
#: blocks per run: one per BLOCK_S seconds, between N_BLOCKS_MIN and N_BLOCKS (enough held-out blocks for
#: the block bootstrap to have power, each still long enough to hold a move and its pause)
N_BLOCKS = 24
N_BLOCKS_MIN = 10
BLOCK_S = 30.0


class HoldoutError(ValueError):
    """A --holdout spec that cannot be applied to these runs."""


@dataclass
class Holdout:
    spec: str
    description: str
    blocks: list[dict] = field(default_factory=list)   # {run, t_start, t_end, heldout}
    kinds: dict[str, dict] = field(default_factory=dict)   # kind -> {"train": n, "heldout": n}
    one_sided: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        return {"spec": self.spec, "description": self.description, "blocks": self.blocks, "kinds": self.kinds,
                "one_sided_kinds": self.one_sided}


def excitation_events(r: RunInputs) -> dict[str, np.ndarray]:
    """Sample index of each excitation event, by kind."""
    n = len(r)
    mv = r.moving
    starts = np.flatnonzero(np.r_[mv[:1], mv[1:] & ~mv[:-1]])
    ends = np.flatnonzero(np.r_[mv[1:] < mv[:-1], mv[-1:]])
    up, down, peak = [], [], []
    top = float(np.max(np.abs(r.turns))) if n else 0.0
    for a, b in zip(starts, ends):
        before, after = abs(r.turns[max(a - 1, 0)]), abs(r.turns[min(b + 1, n - 1)])
        if after > before:
            up.append(a)
            if after >= 0.8 * top > 0:
                peak.append(b)
        elif after < before:
            down.append(a)
    still = ~mv
    s0 = np.flatnonzero(np.r_[still[:1], still[1:] & ~still[:-1]])
    s1 = np.flatnonzero(np.r_[still[1:] < still[:-1], still[-1:]])
    holds = [a for a, b in zip(s0, s1) if r.t[b] - r.t[a] >= 2.0]
    vstep = np.flatnonzero(np.diff(r.volts) != 0) + 1
    von = np.flatnonzero(np.r_[r.volts[:1] > 0, (r.volts[1:] > 0) & (r.volts[:-1] <= 0)])
    lchg = np.flatnonzero(np.abs(np.diff(r.load_g)) > 1.0) + 1
    return {"twist_up": np.array(up, int), "twist_down": np.array(down, int), "twist_peak": np.array(peak, int),
            "hold": np.array(holds, int),
            "heater_step": vstep, "heater_on": von, "load_change": lchg}


def _blocks(r: RunInputs, n_blocks: int) -> list[tuple[int, int]]:
    """Contiguous [start, end) blocks of similar duration cut at segment boundaries."""
    n = len(r)
    bounds = np.flatnonzero(np.diff(r.segment) != 0) + 1
    if len(bounds) < 2:
        bounds = np.arange(1, n)
    cuts = []
    for k in range(1, n_blocks):
        target = r.t[0] + r.duration_s * k / n_blocks
        i = int(np.searchsorted(r.t, target))
        j = int(bounds[np.argmin(np.abs(bounds - i))])
        if 0 < j < n and (not cuts or j > cuts[-1]):
            cuts.append(j)
    edges = [0, *cuts, n]
    return [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def _key(h: np.ndarray, counts: np.ndarray, total: np.ndarray, dur: np.ndarray) -> tuple:
    """How good a held-out choice ``h`` (mask over blocks) is, smaller better: kinds on one side
    only, then the distance of each kind's and the time's held-out share from the target,
    then the shortest gap between held-out blocks (spread them out)."""
    held = counts[:, h].sum(axis=1)
    multi = total >= 2
    missing = int(np.sum(multi & ((held == 0) | (held == total))))
    share = np.where(total > 0, held / np.maximum(total, 1), TARGET_FRACTION)
    balance = float(np.sum(np.abs(share - TARGET_FRACTION)[multi]))
    frac = abs(dur[h].sum() / max(dur.sum(), 1e-9) - TARGET_FRACTION)
    pos = np.flatnonzero(h)
    spread = -int(np.min(np.diff(pos))) if len(pos) > 1 else 0
    return missing, round(balance + frac, 6), spread, tuple(pos)


def _choose(blocks: list[tuple[int, int]], events: dict[str, np.ndarray], t: np.ndarray) -> tuple[set[int], list[str]]:
    """Held-out blocks (never the first): evenly spaced starts, then single swaps of a held-out and a
    training block while they make :func:`_key` smaller (a local search: the exhaustive one grows
    as the binomial coefficient of the block count)."""
    counts = np.array([[int(np.sum((ev >= a) & (ev < b))) for a, b in blocks] for ev in events.values()])
    kinds = list(events)
    total = counts.sum(axis=1)
    dur = np.array([t[b - 1] - t[a] for a, b in blocks], float)
    nb = len(blocks)
    k = min(max(1, int(round(TARGET_FRACTION * nb))), nb - 1)
    best, best_key = None, None
    step = (nb - 1) / k
    for offset in np.linspace(0.0, step, 4, endpoint=False):
        pos = np.unique(np.clip(np.round(1 + offset + step * np.arange(k)).astype(int), 1, nb - 1))
        h = np.zeros(nb, bool)
        h[pos] = True
        key = _key(h, counts, total, dur)
        if best_key is None or key < best_key:
            best, best_key = h, key
    assert best is not None
    for _ in range(4 * nb):
        improved = None
        for i in np.flatnonzero(best):
            for j in np.flatnonzero(~best[1:]) + 1:
                h = best.copy()
                h[i], h[j] = False, True
                key = _key(h, counts, total, dur)
                if key < best_key:
                    improved, best_key = h, key
        if improved is None:
            break
        best = improved
    chosen = set(int(i) for i in np.flatnonzero(best))
    held = counts[:, best].sum(axis=1)
    one_sided = [kk for kk, tot, hh in zip(kinds, total, held) if tot >= 2 and (hh == 0 or hh == tot)]
    return chosen, one_sided


def _kind_table(runs: list[RunInputs]) -> dict[str, dict]:
    out = {k: {"train": 0, "heldout": 0} for k in KINDS}
    for r in runs:
        for kind, ev in excitation_events(r).items():
            h = r.heldout[ev] if len(ev) else np.zeros(0, bool)
            out[kind]["heldout"] += int(h.sum())
            out[kind]["train"] += int((~h).sum())
    return {k: v for k, v in out.items() if v["train"] + v["heldout"] > 0}


def split(runs: list[RunInputs], spec: str | None) -> Holdout:
    """Set each run's ``heldout`` mask from SPEC (None: the default); see the module docstring."""
    for r in runs:
        r.heldout = np.zeros(len(r), bool)
    if spec is None:
        return _default(runs)
    kind, _, arg = spec.partition(":")
    try:
        value = float(arg)
    except ValueError:
        raise HoldoutError(f"holdout {spec!r}: expected run:N, after:SECONDS or fraction:F") from None
    if kind == "run":
        k = int(value)
        if len(runs) < 2:
            raise HoldoutError(f"holdout {spec!r}: holding out a whole run needs several runs")
        if not -len(runs) <= k < len(runs) or k != value:
            raise HoldoutError(f"holdout {spec!r}: only {len(runs)} runs (0 to {len(runs) - 1})")
        runs[k].heldout[:] = True
        desc = f"whole run {k} ({runs[k].name})"
    elif kind == "after":
        for r in runs:
            r.heldout = r.t >= value
        if not any(r.heldout.any() for r in runs) or all(r.heldout.all() for r in runs):
            raise HoldoutError(f"holdout {spec!r}: leaves no held-out or no training samples")
        desc = f"samples at t >= {value:g} s"
    elif kind == "fraction":
        if not 0.0 < value < 1.0:
            raise HoldoutError(f"holdout {spec!r}: the fraction must be in (0, 1)")
        for r in runs:
            i = int(np.searchsorted(r.t, r.t[-1] - value * r.duration_s))
            r.heldout[i:] = True
        desc = f"the last {100 * value:g} % of each run's time"
    else:
        raise HoldoutError(f"holdout {spec!r}: expected run:N, after:SECONDS or fraction:F")
    h = Holdout(spec, desc, _span_blocks(runs))
    h.kinds = _kind_table(runs)
    h.one_sided = [k for k, v in h.kinds.items() if v["train"] + v["heldout"] >= 2 and not (v["train"] and v["heldout"])]
    return h


def _span_blocks(runs: list[RunInputs]) -> list[dict]:
    out = []
    for i, r in enumerate(runs):
        for kind, mask in (("heldout", r.heldout), ("train", ~r.heldout)):
            d = np.diff(np.r_[0, mask.astype(np.int8), 0])
            for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
                out.append({"run": i, "t_start": float(r.t[a]), "t_end": float(r.t[b - 1]), "heldout": kind == "heldout"})
    return sorted(out, key=lambda b: (b["run"], b["t_start"]))


def _default(runs: list[RunInputs]) -> Holdout:
    if len(runs) > 1:
        ev = [excitation_events(r) for r in runs]
        last = {k for k, v in ev[-1].items() if len(v)}
        others = {k for e in ev[:-1] for k, v in e.items() if len(v)}
        if last == others:
            runs[-1].heldout[:] = True
            h = Holdout("default", f"whole last run ({runs[-1].name}): it has the same kinds of excitation as the "
                                   "others", _span_blocks(runs))
            h.kinds = _kind_table(runs)
            return h
    one_sided: list[str] = []
    for r in runs:
        blocks = _blocks(r, int(np.clip(r.duration_s // BLOCK_S, N_BLOCKS_MIN, N_BLOCKS)))
        if len(blocks) < 3:
            i = int(np.searchsorted(r.t, r.t[-1] - TARGET_FRACTION * r.duration_s))
            r.heldout[i:] = True
            continue
        chosen, sided = _choose(blocks, excitation_events(r), r.t)
        one_sided += sided
        for j in chosen:
            a, b = blocks[j]
            r.heldout[a:b] = True
    h = Holdout("default", "contiguous blocks cut at segment boundaries, about 30 % of the time, chosen so that "
                           "every kind of excitation is on both sides", _span_blocks(runs))
    h.kinds = _kind_table(runs)
    h.one_sided = sorted(set(one_sided))
    return h


def units(r: RunInputs, min_s: float = 20.0, per_block: int = 6) -> list[np.ndarray]:
    """Held-out sample indices of ``r`` as contiguous resampling units cut at segment boundaries."""
    out = []
    d = np.diff(np.r_[0, r.heldout.astype(np.int8), 0])
    seg_b = np.flatnonzero(np.diff(r.segment) != 0) + 1
    for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
        span = r.t[b - 1] - r.t[a]
        k = int(max(1, min(per_block, span // min_s)))
        cuts = [a]
        for j in range(1, k):
            i = int(np.searchsorted(r.t, r.t[a] + span * j / k))
            inner = seg_b[(seg_b > cuts[-1]) & (seg_b < b)]
            if len(inner):
                c = int(inner[np.argmin(np.abs(inner - i))])
                if c > cuts[-1]:
                    cuts.append(c)
        cuts.append(b)
        out += [np.arange(x, y) for x, y in zip(cuts[:-1], cuts[1:]) if y > x]
    return out
