"""The extended model `tsa-bench diagnose --write-model` writes: the judged bench file with the
named effects, the recalibrated parameters and the named variance components in its plant.

Units: as a bench file (docs/bench-config.md): mm, ohm, s, g.

Contract: :func:`model_text` returns the bench file's text: a comment header (what was
judged on which runs, the verdict, what was named, the final held-out RMSE with full
precision and the ``predict`` command that gives it back bit for bit) and the judged
bench file's mapping with ``plant`` replaced by the result's extended model
(``result.model_plant``; only named causes are switched on in it). :func:`write_model`
writes it (never over an existing file, never partly: a temporary file beside it is
renamed) and reads it back with the bench loader, so that ``tsa-bench run --bench``,
``predict`` and ``diagnose --model`` take it; a file the loader refuses is removed and
the error raised.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import yaml

from tsa_bench.analysis.result import plain


class ModelWriteError(ValueError):
    """The extended model cannot be written (exists, empty result, refused by the bench loader)."""


def _header(result: Any, judged: str | Path, holdout: str | None) -> list[str]:
    prov = getattr(result, "provenance", {}) or {}
    runs = ", ".join(f"{Path(i.get('path', '')).name} (sha256 {str(i.get('sha256'))[:12]})"
                     for i in prov.get("inputs", []))
    named = [f"{c.effect} ({c.form})" for c in result.named]
    gains = ", ".join(f"{g.output} {g.heldout_rmse_after!r} {'mm' if g.output == 'length' else 'ohm'}"
                      for g in result.gain)
    spec = f" --holdout {holdout}" if holdout else ""
    first = Path((prov.get("inputs") or [{}])[0].get("path", "RUN.h5")).name
    return [
        "# Extended model written by `tsa-bench diagnose --write-model`: the judged bench file with the",
        "# named effects switched on and every parameter recalibrated (only named causes are on).",
        f"# judged model: {judged}",
        f"# runs: {runs}",
        f"# verdict: {result.summary}",
        f"# named: {', '.join(named) or 'nothing'}",
        f"# held-out RMSE of this model: {gains}",
        f"# reproduce it: tsa-bench predict THIS.yaml {first}{spec}",
    ]


def model_text(result: Any, judged: str | Path, holdout: str | None = None) -> str:
    """The bench file's text (module docstring)."""
    if not getattr(result, "model_plant", None):
        raise ModelWriteError("the diagnosis ended before a model was calibrated (model_mismatch on the inputs): "
                              "there is no extended model to write")
    bench = yaml.safe_load(Path(judged).read_text())
    bench["plant"] = plain(result.model_plant)
    if isinstance(bench.get("name"), str):
        bench["name"] = f"{bench['name']} (extended by diagnose)"
    body = yaml.safe_dump(bench, sort_keys=False, default_flow_style=False)
    return "\n".join(_header(result, judged, holdout)) + "\n" + body


def write_model(result: Any, judged: str | Path, out: str | Path, holdout: str | None = None) -> Path:
    """Write the extended model to ``out`` (module docstring); returns its path."""
    from tsa_bench.bench import load_bench

    p = Path(out)
    if p.exists():
        raise ModelWriteError(f"{p} already exists; choose another --write-model file (nothing is overwritten)")
    text = model_text(result, judged, holdout)
    tmp = p.with_name(f".{p.name}.partial")
    tmp.write_text(text)
    try:
        load_bench(tmp)
    except Exception as exc:
        tmp.unlink(missing_ok=True)
        raise ModelWriteError(f"{p}: the bench loader refuses the extended model ({exc})") from None
    os.replace(tmp, p)
    return p
