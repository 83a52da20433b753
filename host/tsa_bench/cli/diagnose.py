"""`tsa-bench diagnose`: judge the simulation against measured runs, end in a verdict.

Exit codes: 0 the diagnosis ran (whatever the verdict: explained, named, unexplained or
model_mismatch); 1 the engine failed unexpectedly or the report could not be written;
2 bad input (a run file that breaks the contract, a bad model file, a bad --holdout,
--outputs or --max-causes, a --write-model file that exists, a --validate run that is one of
the runs or lacks an input), nothing written; 130 interrupted (Ctrl-C), nothing written.
Progress goes to stderr; the report to stdout and, by default, beside the first run
(``<run>_diagnose/``), as ``tsa-bench report`` does.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import click

from tsa_bench.cli.exits import (
    EXIT_ABORTED, EXIT_FAILED, check_output, check_output_folder, fail, unwritable_reason,
)
from tsa_bench.cli.loading import FORCE, MAX_MEMORY


def _default_out(first_run: str) -> Path:
    p = Path(first_run)
    return p.with_name(p.stem + "_diagnose")


def _no_segments_hint(run: Any) -> str:
    """What to do about a run without segments: infer them, or, when the import inferred none, why."""
    import json

    try:
        seg = json.loads(run.attrs.get("metadata", "{}")).get("segments", {})
    except (TypeError, ValueError, AttributeError):
        seg = {}
    if isinstance(seg, dict) and seg.get("mode") == "infer":
        return ("its import inferred none: no move, heater or load change above the thresholds; "
                "tsa-bench import --segment-threshold lowers them")
    return "tsa-bench import --segments infer finds them"


@click.command()
@click.argument("run_files", metavar="RUN.h5 [RUN2.h5 ...]", nargs=-1, required=True,
                type=click.Path(dir_okay=False))
@click.option("--model", "model_path", type=click.Path(dir_okay=False), default=None,
              help="Bench file whose plant is the simulation being judged "
                   "(default: configs/bench/sim-baseline.yaml, the thesis-level baseline).")
@click.option("--holdout", default=None,
              help="Held-out part: run:N (a whole run, several runs), after:SECONDS or fraction:F (the last "
                   "fraction F); default: contiguous blocks that keep every kind of excitation on both sides.")
@click.option("--outputs", default="length,resistance", show_default=True,
              help="Outputs to judge, comma-separated (length, resistance).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Directory for report.txt, the figures and diagnose.json (default: <first run>_diagnose/ next "
                   "to it).")
@click.option("--json", "json_path", type=click.Path(dir_okay=False), default=None,
              help="JSON result file (default: <out>/diagnose.json).")
@click.option("--max-causes", type=int, default=6, show_default=True,
              help="Most effects in the model at once (a demoted one frees its place).")
@click.option("--write-model", "model_out", type=click.Path(dir_okay=False), default=None, metavar="OUT.yaml",
              help="Write the extended model: the judged bench file with the named effects and variance components "
                   "and every parameter recalibrated (tsa-bench predict / run --bench / diagnose --model read it; "
                   "never overwritten).")
@click.option("--validate", "validate_files", multiple=True, type=click.Path(dir_okay=False), metavar="RUN2.h5",
              help="Run never used to calibrate or select (repeatable): scored with the judged and the extended "
                   "model, printed beside the held-out figures (prospective validation).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the bootstrap resampling.")
@click.option("--quiet", "-q", is_flag=True, help="No progress lines on stderr.")
@click.option("--catalogue", "catalogue_url", default=None, metavar="URL",
              help="Catalogue the verdict is registered in, on each run's row (default: $TSA_BENCH_CATALOGUE, "
                   "else catalogue.sqlite beside each run file; 'none': not registered).")
@MAX_MEMORY
@FORCE
def diagnose(run_files: tuple[str, ...], model_path: str | None, holdout: str | None, outputs: str,
             out_dir: str | None, json_path: str | None, max_causes: int, model_out: str | None,
             validate_files: tuple[str, ...], seed: int, quiet: bool, catalogue_url: str | None, force: bool) -> None:
    """Judge the simulation on RUN.h5: a verdict (explained, named, unexplained, model_mismatch), the cause, the gain.

    A report folder that already holds files, or an existing --json file, is refused unless --force
    (the --write-model file is never overwritten, --force or not).
    """
    try:
        result = _diagnose(run_files, model_path, holdout, outputs, out_dir, json_path, max_causes, model_out,
                           validate_files, seed, quiet, force)
    except KeyboardInterrupt:
        click.echo("diagnose: interrupted; nothing written", err=True)
        sys.exit(EXIT_ABORTED)
    from tsa_bench.cli.catalogue import register_verdict

    register_verdict(catalogue_url, list(run_files), result.verdict, result.cause or result.summary)


def _read_runs(paths: tuple[str, ...]) -> list:
    from tsa_bench.store import RunFileError, read_run

    runs = []
    for path in paths:  # read first: a run without segments is said on the first line
        try:
            runs.append(read_run(path))
        except RunFileError as exc:
            fail(str(exc))
        except Exception as exc:  # any reader surprise is still bad input, named by file
            fail(f"{path}: cannot read the run file ({type(exc).__name__}: {exc})")
    return runs


def _diagnose(run_files: tuple[str, ...], model_path: str | None, holdout: str | None, outputs: str,
              out_dir: str | None, json_path: str | None, max_causes: int, model_out: str | None,
              validate_files: tuple[str, ...], seed: int, quiet: bool, force: bool):
    """The diagnose result, once its report is written and the extended model with it (exits on any problem)."""
    if max_causes < 0:
        fail(f"--max-causes must be >= 0, got {max_causes}")
    if model_out is not None and Path(model_out).exists():
        fail(f"{model_out} already exists; choose another --write-model file (nothing is overwritten)")
    overlap = set(map(str, map(Path, validate_files))) & set(map(str, map(Path, run_files)))
    if overlap:
        fail(f"--validate {sorted(overlap)[0]}: a validation run must not be one of the runs diagnosed")
    judged = tuple(o.strip() for o in outputs.split(",") if o.strip())
    if not judged or any(o not in ("length", "resistance") for o in judged):
        fail(f"--outputs {outputs!r}: give length, resistance or both, comma-separated")

    def say(msg: str) -> None:
        if not quiet:
            click.echo(f"diagnose: {msg}", err=True)

    runs = _read_runs(run_files)
    checks = _read_runs(validate_files)
    import numpy as np

    for r in runs:
        if len(r) and not (r.samples["segment"] >= 0).any():
            click.echo(f"diagnose: note: {r.path} has no segments: held-out blocks and resampling units are cut "
                       f"by time alone, not at segment ends ({_no_segments_hint(r)})", err=True)
        if "force" in r.samples and not np.isfinite(np.asarray(r.samples["load"], float)).any():
            click.echo(f"diagnose: note: {r.path} has a measured force (the force column) and no declared load: "
                       "the model's initial load is used as the load, not the measured force", err=True)
    say(f"read {', '.join(run_files)}")
    if any(len(r) == 0 for r in runs):
        empty = next(r.path for r in runs if len(r) == 0)
        fail(f"{empty}: the run has no samples; nothing to diagnose")

    out = Path(out_dir) if out_dir else _default_out(run_files[0])
    for target in (out, Path(json_path) if json_path else None, Path(model_out) if model_out else None):
        why = unwritable_reason(target) if target is not None else None
        if why:
            fail(f"{target}: cannot write the report there ({why}); nothing was analysed")
    check_output_folder(out, force)
    check_output(json_path, force)

    from tsa_bench import analysis

    shown = model_path or str(analysis.BASELINE)
    try:
        model = analysis.load_model(model_path)
    except Exception as exc:
        msg = str(exc)
        fail(msg if model_path and model_path in msg else f"{shown}: {msg}")
    from tsa_bench.analysis.inputs import missing_inputs, run_inputs

    for r in checks:
        miss = missing_inputs([run_inputs(r, float(model.get("initial_load_g", 0.0)))], judged)
        if miss:
            fail(f"--validate {r.path}: {miss[0][0]} ({miss[0][1]})")
    try:
        result = analysis.diagnose(runs, model, holdout, max_causes=max_causes, seed=seed, progress=say,
                                   outputs=judged, model_path=shown, validate=checks)
    except analysis.HoldoutError as exc:
        fail(f"--holdout {holdout!r}: {exc}" if holdout and holdout not in str(exc) else str(exc))
    except (KeyboardInterrupt, SystemExit):
        raise
    except Exception as exc:  # an engine failure is reported in one line, not as a traceback
        fail(f"diagnose failed on {', '.join(run_files)}: {type(exc).__name__}: {exc}", EXIT_FAILED)

    from tsa_bench.outputs import OutputExists
    from tsa_bench.report.diagnose_report import write_json, write_report

    say(f"writing the report into {out}")
    try:
        paths = write_report(result, runs, out)
        jpath = write_json(result, Path(json_path) if json_path else out / "diagnose.json")
    except OutputExists as exc:
        fail(str(exc))
    except OSError as exc:
        fail(f"cannot write the report into {out}: {exc}", EXIT_FAILED)
    written = []
    if model_out is not None:
        from tsa_bench.report.diagnose_model import ModelWriteError, write_model

        try:
            written.append(write_model(result, shown, model_out, holdout))
        except ModelWriteError as exc:
            fail(str(exc), EXIT_FAILED)
        except OSError as exc:
            fail(f"cannot write the extended model {model_out}: {exc}", EXIT_FAILED)
    click.echo(paths["report"].read_text(), nl=False)
    click.echo("")
    for p in [*paths.values(), jpath, *written]:
        click.echo(f"wrote {p}")
    return result
