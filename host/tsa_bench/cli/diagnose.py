"""`tsa-bench diagnose`: judge the simulation against measured runs.

Exit codes: 0 the diagnosis ran (whether or not a cause was found); 1 the engine
failed unexpectedly; 2 bad input (a run file that breaks the contract, a bad model file,
a bad --holdout or --max-causes), nothing written.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import click

from tsa_bench.cli.exits import EXIT_BAD_INPUT, EXIT_FAILED


def _fail(message: str, code: int = EXIT_BAD_INPUT) -> None:
    click.echo(f"error: {message}", err=True)
    sys.exit(code)


def _default_out(first_run: str) -> Path:
    stem = re.sub(r"[^A-Za-z0-9_.-]+", "-", Path(first_run).stem).strip("-") or "run"
    return Path.cwd() / f"diagnose-{stem}"


@click.command()
@click.argument("run_files", metavar="RUN.h5 [RUN2.h5 ...]", nargs=-1, required=True,
                type=click.Path(dir_okay=False))
@click.option("--model", "model_path", type=click.Path(dir_okay=False), default=None,
              help="Bench file whose plant is the simulation being judged "
                   "(default: configs/bench/sim-baseline.yaml, the thesis-level baseline).")
@click.option("--holdout", default=None,
              help="Held-out part, never interleaved with training samples: run:N (run N, several "
                   "runs), after:SECONDS (samples after that time) or fraction:F (the last fraction F); "
                   "default: chosen by the engine.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Directory for report.txt and the figures (default: ./diagnose-<first run stem>/).")
@click.option("--json", "json_path", type=click.Path(dir_okay=False), default=None,
              help="JSON result file (default: <out>/diagnose.json).")
@click.option("--max-causes", type=int, default=3, show_default=True,
              help="Most effects named, one per iteration.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of any random choice in the engine.")
def diagnose(run_files: tuple[str, ...], model_path: str | None, holdout: str | None, out_dir: str | None,
             json_path: str | None, max_causes: int, seed: int) -> None:
    """Show what the simulation gets wrong on RUN.h5, name the cause, extend the model, measure the gain."""
    from tsa_bench.store import RunFileError, read_run

    if max_causes < 0:
        _fail(f"--max-causes must be >= 0, got {max_causes}")
    runs = []
    for path in run_files:
        try:
            runs.append(read_run(path))
        except RunFileError as exc:
            _fail(str(exc))
        except Exception as exc:  # any reader surprise is still bad input, named by file
            _fail(f"{path}: cannot read the run file ({type(exc).__name__}: {exc})")
    if any(len(r) == 0 for r in runs):
        empty = next(r.path for r in runs if len(r) == 0)
        _fail(f"{empty}: the run has no samples; nothing to diagnose")

    try:
        from tsa_bench import analysis
        analysis.diagnose, analysis.load_model  # noqa: B018  (both are the engine's API)
    except (ImportError, AttributeError) as exc:
        _fail(f"the diagnose engine (tsa_bench.analysis) is not available: {exc}", EXIT_FAILED)

    try:
        model = analysis.load_model(model_path)
    except Exception as exc:
        shown = model_path or "the default model (configs/bench/sim-baseline.yaml)"
        msg = str(exc)
        _fail(msg if model_path and model_path in msg else f"{shown}: {msg}")

    holdout_error = getattr(analysis, "HoldoutError", None)
    try:
        result = analysis.diagnose(runs, model, holdout, max_causes=max_causes, seed=seed)
    except Exception as exc:
        if holdout_error is not None and isinstance(exc, holdout_error):
            _fail(f"--holdout {holdout!r}: {exc}")
        if holdout is not None and isinstance(exc, ValueError) and "holdout" in str(exc).lower():
            _fail(f"--holdout {holdout!r}: {exc}" if holdout not in str(exc) else str(exc))
        if isinstance(exc, ValueError):
            _fail(f"{', '.join(run_files)}: {exc}")
        raise

    from tsa_bench.report.diagnose_report import write_json, write_report

    out = Path(out_dir) if out_dir else _default_out(run_files[0])
    try:
        paths = write_report(result, runs, out)
        jpath = write_json(result, Path(json_path) if json_path else out / "diagnose.json")
    except OSError as exc:
        _fail(f"cannot write the report into {out}: {exc}", EXIT_FAILED)
    click.echo(paths["report"].read_text(), nl=False)
    click.echo("")
    for key, p in paths.items():
        click.echo(f"wrote {p}")
    click.echo(f"wrote {jpath}")
