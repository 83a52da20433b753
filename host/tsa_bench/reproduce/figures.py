"""One figure per thesis chapter: every compared record, simulated against thesis in tolerance units.

Units: the horizontal axis is the residual of :func:`tsa_bench.reproduce.table.residual`
(simulated minus thesis in units of the record's tolerance; the band |r| <= 1 is
agreement), clipped to +-10.

Contract: :func:`write_figures` writes ``chapter<N>.png`` for every chapter with at
least one simulated record into ``out_dir`` (Agg backend, no window) and returns the
paths. Each record is one row, labelled with its id, at its median over the seeds;
colour = verdict, marker = role (held-out, fitted, built-from; the rows never counted --
derived, duplicate, uninformative -- and the qualitative ones as crosses); rows that are
not simulated are left out and counted in the title.
"""

from __future__ import annotations

import math
from pathlib import Path

from tsa_bench.outputs import save_figure
from tsa_bench.reproduce.records import Record
from tsa_bench.reproduce.table import Row, residual

COLOURS = {"agrees": "tab:green", "disagrees": "tab:red", "consistency-only": "tab:gray", "not computed": "k"}
MARKERS = {"fitted": "s", "held-out": "o", "built-from": "D", "derived": "x", "duplicate": "x", "uninformative": "x",
           "qualitative": "+"}
CLIP = 10.0


def write_figures(records: list[Record], rows: list[Row], out_dir: str | Path) -> list[Path]:
    import matplotlib
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    by_id = {r.id: r for r in records}
    paths = []
    for chapter in sorted({r.chapter for r in rows}):
        rows_c = [r for r in rows if r.chapter == chapter and r.simulated is not None]
        skipped = sum(1 for r in rows if r.chapter == chapter and r.simulated is None)
        if not rows_c:
            continue
        fig, ax = plt.subplots(figsize=(10, 1.2 + 0.16 * len(rows_c)))
        ax.axvspan(-1, 1, color="tab:green", alpha=0.12, lw=0)
        ax.axvline(0, color="k", lw=0.6)
        for i, r in enumerate(rows_c):
            res = residual(by_id[r.id], r.simulated)
            x = max(-CLIP, min(CLIP, res)) if math.isfinite(res) else CLIP
            ax.plot([x], [i], MARKERS.get(r.role, "o"), color=COLOURS.get(r.verdict, "k"), ms=4.5,
                    mfc="none" if r.role == "fitted" else COLOURS.get(r.verdict, "k"))
        ax.set_yticks(range(len(rows_c)))
        ax.set_yticklabels([r.id for r in rows_c], fontsize=6)
        ax.set_ylim(len(rows_c) - 0.5, -0.5)
        ax.set_xlim(-CLIP - 0.5, CLIP + 0.5)
        ax.set_xlabel("(simulated - thesis) in units of the record's tolerance (|x| <= 1: agrees; clipped at 10)")
        n = {v: sum(r.verdict == v for r in rows_c) for v in COLOURS}
        held = [r for r in rows_c if r.role == "held-out" and r.verdict in ("agrees", "disagrees")]
        ax.set_title(f"Thesis chapter {chapter}: {n['agrees']} agree, {n['disagrees']} disagree, "
                     f"{n['consistency-only']} consistency-only; held out: "
                     f"{sum(r.verdict == 'agrees' for r in held)}/{len(held)} agree; {skipped} not simulated\n"
                     "filled circle = held out, open square = fitted, diamond = built from the record, "
                     "x = derived / duplicate / uninformative (never counted), + = qualitative",
                     fontsize=9)
        ax.grid(axis="x", alpha=0.3)
        fig.tight_layout()
        path = out / f"chapter{chapter}.png"
        save_figure(fig, path, dpi=100)
        plt.close(fig)
        paths.append(path)
    return paths
