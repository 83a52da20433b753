"""`tsa-bench sweep`: a study of many simulated points on Dask distributed (docs/sweep.md).

Exit codes: 0 the sweep ran to its end (points that failed are rows of the table, counted
in the last line) or the report was drawn; 1 the cluster could not be reached or started
(the message names the scheduler's address), or the results could not be written;
2 bad input (the study file, with file:line:col; a bad option), nothing run;
130 interrupted (Ctrl-C): the pending points are cancelled, the finished ones kept.
"""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import click

from tsa_bench.cli.exits import EXIT_ABORTED, EXIT_FAILED, check_output_folder, fail
from tsa_bench.cli.loading import FORCE


@click.command("sweep")
@click.argument("study_file", metavar="STUDY.yaml", type=click.Path(dir_okay=False))
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Results folder (default: sweeps/<study name>/ in the current folder).")
@click.option("--scheduler", default=None, metavar="tcp://HOST:PORT",
              help="Address of a running Dask scheduler (default: a local cluster started for the sweep).")
@click.option("--workers", type=int, default=None,
              help="Worker processes of the local cluster (default: the machine's cores).")
@click.option("--connect-timeout", "timeout_s", type=float, default=10.0, show_default=True,
              help="Seconds to wait for --scheduler to answer.")
@click.option("--retry-failed", is_flag=True, help="Run the points that failed in an earlier sweep again.")
@click.option("--report", "report_only", is_flag=True,
              help="Run nothing: draw the figures of the results so far (figure of merit vs each varied "
                   "parameter, rates with 95 % intervals) into <out>/report/.")
@click.option("--dry-run", is_flag=True, help="Validate the study and list its points; run nothing.")
@click.option("--quiet", "-q", is_flag=True, help="No progress on stderr.")
@FORCE
def sweep(study_file: str, out_dir: str | None, scheduler: str | None, workers: int | None, timeout_s: float,
          retry_failed: bool, report_only: bool, dry_run: bool, quiet: bool, force: bool) -> None:
    """Run the points of STUDY.yaml (grids, lists, seeded draws) and keep one row per point in a Parquet table."""
    import importlib.util

    missing_extra = [m for m in ("distributed", "pyarrow") if importlib.util.find_spec(m) is None]
    if missing_extra:
        fail(f"tsa-bench sweep needs {' and '.join(missing_extra)}: pip install 'tsa-bench[sweep]'", EXIT_FAILED)
    from tsa_bench.userfiles import DocumentError
    from tsa_bench.sweep import load_study
    from tsa_bench.sweep.table import ResultsTable, ResultsTableError

    if not timeout_s > 0:
        fail(f"--connect-timeout must be > 0, got {timeout_s}")
    if workers is not None and workers < 1:
        fail(f"--workers must be >= 1, got {workers}")
    if workers is not None and scheduler:
        fail("--workers sizes the local cluster; an existing --scheduler has its own workers")
    if scheduler is not None and not scheduler.startswith(("tcp://", "tls://", "inproc://", "ucx://")):
        fail(f"--scheduler {scheduler!r}: give the scheduler's address, tcp://HOST:PORT")
    from tsa_bench.shipped import find_config

    found, from_shipped = find_config(study_file, "studies")
    if from_shipped:
        click.echo(f"sweep: using the shipped study {found}", err=True)
    try:
        study = load_study(found)
    except DocumentError as exc:
        fail(str(exc))
    folder = Path(out_dir) if out_dir else Path("sweeps") / study.name
    table = ResultsTable(folder)
    try:
        finished = table.finished_keys(include_failed=not retry_failed)
    except ResultsTableError as exc:
        fail(str(exc))
    missing = sum(p.key not in finished for p in study.points)
    say = (lambda msg: None) if quiet else (lambda msg: click.echo(f"sweep: {msg}", err=True))
    if report_only:
        check_output_folder(folder / "report", force)
        _report(study, table, folder)
        return
    if dry_run:
        for p in study.points:
            mark = "to run" if p.key not in finished else "in results"
            click.echo(f"{p.index:>6} {p.key} {mark:<10} " + " ".join(f"{k}={v}" for k, v in p.varied.items()))
        click.echo(f"{len(study.points)} points, {missing} to run, runner {study.runner}, results {folder}")
        return
    where = scheduler or f"a local cluster of {workers or _cores()} worker process(es)"
    say(f"study {study.name!r}: {len(study.points)} points, {len(study.points) - missing} already in {folder}, "
        f"{missing} to run on {where}")
    previous = signal.signal(signal.SIGTERM, _terminated)   # SIGTERM stops a sweep as Ctrl-C does
    try:
        _run(study, table, folder, scheduler, workers, timeout_s, retry_failed, quiet)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _terminated(signum, frame) -> None:
    raise KeyboardInterrupt("SIGTERM")


def _cores() -> int:
    from tsa_bench.sweep.engine import default_workers

    return default_workers()


def _run(study, table, folder: Path, scheduler: str | None, workers: int | None, timeout_s: float,
         retry_failed: bool, quiet: bool) -> None:
    from tsa_bench.sweep.engine import Interrupted, SchedulerUnreachable, run_study
    from tsa_bench.sweep.progress import SweepProgress

    index = {p.key: p.index for p in study.points}
    try:
        if quiet:
            summary = run_study(study, table, scheduler=scheduler, workers=workers, retry_failed=retry_failed,
                                timeout_s=timeout_s)
        else:
            with SweepProgress(f"sweep {study.name}") as progress:
                summary = run_study(study, table, scheduler=scheduler, workers=workers, retry_failed=retry_failed,
                                    progress=progress, timeout_s=timeout_s)
    except SchedulerUnreachable as exc:
        fail(str(exc), EXIT_FAILED)
    except Interrupted as exc:
        s = exc.summary
        _consolidate(table, index)
        click.echo(f"sweep: interrupted; {s.done + s.failed} points finished and kept in {folder}, the rest "
                   "cancelled (run the same command again to finish them)", err=True)
        sys.exit(EXIT_ABORTED)
    except KeyboardInterrupt:
        click.echo(f"sweep: interrupted while starting; finished points are kept in {folder}", err=True)
        sys.exit(EXIT_ABORTED)
    except OSError as exc:
        fail(f"cannot write the results into {folder}: {exc}", EXIT_FAILED)
    path = _consolidate(table, index)
    per = f", {summary.work_s / max(summary.done + summary.failed, 1):.2f} s of work per point" \
        if summary.done + summary.failed else ""
    click.echo(f"sweep: {summary.done} done, {summary.failed} failed, {summary.skipped} already in the results "
               f"({summary.total} points) in {summary.wall_s:.1f} s on {summary.workers or '-'} worker(s){per}")
    if path is not None:
        click.echo(f"wrote {path}")


def _consolidate(table, index: dict[str, int]) -> Path | None:
    try:
        return table.consolidate(index)
    except OSError as exc:
        fail(f"cannot write {table.folder / 'results.parquet'}: {exc}", EXIT_FAILED)


def _report(study, table, folder: Path) -> None:
    from tsa_bench.sweep.report import write_report

    try:
        paths = write_report(study, table, folder / "report")
    except OSError as exc:
        fail(f"cannot write the report into {folder / 'report'}: {exc}", EXIT_FAILED)
    if not paths:
        fail(f"{folder}: no results yet; run `tsa-bench sweep {study.path}` first", EXIT_FAILED)
    for p in paths:
        click.echo(f"wrote {p}")
