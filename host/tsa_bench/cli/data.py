"""Data commands: `tsa-bench info | report | watch | export` (`import`: :mod:`.importing`; `ls`: :mod:`.catalogue`).

Exit codes as in :mod:`tsa_bench.cli`: 0 success; 1 a watched run ended without success
or was killed; 2 bad input (run file, CSV, options), with a message naming the file and,
for CSV, the line and column.
"""

from __future__ import annotations

import sys

import click

from tsa_bench.cli.exits import EXIT_BAD_INPUT, EXIT_FAILED, check_output_folder, fail
from tsa_bench.cli.loading import FORCE, MAX_MEMORY


@click.command()
@click.argument("run_files", nargs=-1, required=True, type=click.Path(dir_okay=False))
@MAX_MEMORY
def info(run_files: tuple[str, ...]) -> None:
    """Print each RUN_FILE's metadata, exit status, segment summary and sample statistics.

    A run file killed inside a write that cannot be read is rebuilt from its live sidecar
    (the run's journal) into a new file RUN-rebuilt.h5, which is then shown. Exit 2 when
    any of them cannot be read (the others are still shown).
    """
    from tsa_bench.console.summary import format_run_info
    from tsa_bench.store.inspect import RunFileError, inspect_run
    from tsa_bench.store.live import sidecar_path
    from tsa_bench.store.recover import RecoveryError, recover_run

    code = 0
    for i, run_file in enumerate(run_files):
        if i:
            click.echo("")
        try:
            click.echo(format_run_info(inspect_run(run_file)))
        except RunFileError as exc:
            if sidecar_path(run_file).is_file():
                try:
                    rec = recover_run(run_file)
                    click.echo(f"note: {rec.message}", err=True)
                    click.echo(format_run_info(inspect_run(rec.path)))
                    continue
                except (RecoveryError, RunFileError) as again:
                    click.echo(f"error: {again}", err=True)
                    code = EXIT_BAD_INPUT
                    continue
            click.echo(f"error: {exc}", err=True)
            code = EXIT_BAD_INPUT
    sys.exit(code)


@click.command()
@click.argument("run_file", type=click.Path(dir_okay=False))
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Directory for the figures and index.html (default: RUN_report next to the run file).")
@click.option("--format", "fmt", type=click.Choice(["png", "pdf", "svg"]), default="png", show_default=True,
              help="Figure file format.")
@click.option("--dpi", type=click.IntRange(20, 1200), default=150, show_default=True,
              help="Resolution of raster figures (dots per inch).")
@MAX_MEMORY
@FORCE
def report(run_file: str, out_dir: str | None, fmt: str, dpi: int, force: bool) -> None:
    """Write figures chosen by RUN_FILE's content and an index.html showing them.

    A folder that already holds files (an earlier report) is refused unless --force.
    """
    from pathlib import Path

    from tsa_bench.report.run_report import write_run_report
    from tsa_bench.store import RunFileError

    check_output_folder(out_dir or Path(run_file).with_name(Path(run_file).stem + "_report"), force)
    from tsa_bench.outputs import OutputExists

    try:
        rep = write_run_report(run_file, out_dir, fmt=fmt, dpi=dpi)
    except (RunFileError, OutputExists) as exc:
        fail(str(exc))
    except OSError as exc:
        fail(f"cannot write the report ({exc.filename or out_dir or run_file}): {exc.strerror or exc}", EXIT_FAILED)
    for fig in rep.figures:
        click.echo(f"wrote {fig.path}")
    for kind, why in rep.skipped.items():
        click.echo(f"  no {kind} figure: {why}")
    click.echo(f"wrote {rep.index}")


@click.command()
@click.argument("run_file", type=click.Path(dir_okay=False))
@click.option("--plain", is_flag=True, help="One text line per refresh instead of the live table (for logs, tests).")
@click.option("--once", is_flag=True, help="Show the current state once and exit.")
@click.option("--interval", "interval_s", type=float, default=0.5, show_default=True,
              help="Refresh interval (s).")
@click.option("--wait", "wait_s", type=float, default=10.0, show_default=True,
              help="How long to wait for a run that has not started yet (s).")
@MAX_MEMORY
def watch(run_file: str, plain: bool, once: bool, interval_s: float, wait_s: float) -> None:
    """Show RUN_FILE's latest samples while `tsa-bench run` records it; end with the run.

    Reads the run's live sidecar RUN_FILE.live (docs/live-view.md), never the HDF5 file
    being written. Exit code 0 when the run ends in success, 1 when it ends otherwise or
    was killed, 2 when there is nothing to watch.
    """
    from tsa_bench.console.output import make_console
    from tsa_bench.console.watch import watch as do_watch

    if not 0 < interval_s <= 3600:
        fail(f"--interval must be > 0 and at most 3600 s, got {interval_s}")
    if not 0 <= wait_s <= 86400:
        fail(f"--wait must be 0..86400 s, got {wait_s}")
    console = make_console(terminal=False if plain else None)
    sys.exit(do_watch(run_file, plain=plain, once=once, interval_s=interval_s, wait_s=wait_s, console=console))


@click.command()
@click.argument("run_file", type=click.Path(dir_okay=False))
@click.option("--csv", "as_csv", is_flag=True, help="Write CSV files with units in the headers.")
@click.option("--documents", "as_documents", is_flag=True,
              help="Write the run as Bluesky documents, JSON lines of [name, document] (needs the bluesky extra: "
                   'pip install "tsa-bench[bluesky]"; docs/bluesky.md).')
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Directory for the CSV files (default: next to the run file).")
@click.option("--output", "out_file", type=click.Path(dir_okay=False, allow_dash=True), default="-", show_default=True,
              help="--documents: the JSON-lines file to write (- for standard output).")
@MAX_MEMORY
@FORCE
def export(run_file: str, as_csv: bool, as_documents: bool, out_dir: str | None, out_file: str, force: bool) -> None:
    """Write RUN_FILE's samples, segments and events as CSV, or as Bluesky documents.

    Each file is written whole or not at all; an existing one is refused unless --force.
    """
    from tsa_bench.outputs import OutputExists
    from tsa_bench.store import RunFileError

    if as_csv == as_documents:
        fail("choose one format: --csv or --documents")
    if as_documents:
        _export_documents(run_file, out_file)
        return
    from tsa_bench.store.csv_export import export_csv

    try:
        for path in export_csv(run_file, out_dir):
            click.echo(f"wrote {path}")
    except (RunFileError, OutputExists) as exc:
        fail(str(exc))
    except OSError as exc:
        fail(f"cannot write the CSV files ({exc.filename or out_dir}): {exc.strerror or exc}", EXIT_FAILED)


def _export_documents(run_file: str, out_file: str) -> None:
    """`export --documents`: JSON lines to a new file, written whole or not at all (an existing
    file or link refused unless --force, never written through), or to stdout."""
    from pathlib import Path

    from tsa_bench.outputs import OutputExists, open_output
    from tsa_bench.store import RunFileError

    try:
        from tsa_bench.bluesky.export import write_jsonl
    except ImportError as exc:
        fail(f"--documents needs the bluesky extra ({exc.name} is not installed): pip install \"tsa-bench[bluesky]\"")
    if out_file == "-":
        try:
            write_jsonl(run_file, sys.stdout)
        except RunFileError as exc:
            fail(str(exc))
        return
    path = Path(out_file)
    try:
        with open_output(path, "w") as out:
            n = write_jsonl(run_file, out)
    except (RunFileError, OutputExists) as exc:
        fail(f"{exc} (nothing was written)")
    except OSError as exc:
        fail(f"cannot write {path}: {exc.strerror or exc}", EXIT_FAILED)
    click.echo(f"wrote {path} ({n} documents)")
