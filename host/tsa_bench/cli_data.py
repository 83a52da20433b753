"""Command line for data hand-off: `tsa-bench report | watch | import | export`.

Registered on the `tsa-bench` group at the bottom of cli.py. Exit codes as there:
0 success; 1 a watched run ended without success or was killed; 2 bad input (run file,
CSV, options), with a message naming the file and, for CSV, the line and column.
"""

from __future__ import annotations

import sys

import click

EXIT_FAILED, EXIT_BAD_INPUT = 1, 2


@click.command()
@click.argument("run_file", type=click.Path(dir_okay=False))
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Directory for the figures and index.html (default: RUN_report next to the run file).")
def report(run_file: str, out_dir: str | None) -> None:
    """Write PNG figures chosen by RUN_FILE's content and an index.html showing them."""
    from tsa_bench.report.run_report import write_run_report
    from tsa_bench.store import RunFileError

    try:
        rep = write_run_report(run_file, out_dir)
    except RunFileError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(EXIT_BAD_INPUT)
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
def watch(run_file: str, plain: bool, once: bool, interval_s: float, wait_s: float) -> None:
    """Show RUN_FILE's latest samples while `tsa-bench run` records it; end with the run.

    Reads the run's live sidecar RUN_FILE.live (docs/live-view.md), never the HDF5 file
    being written. Exit code 0 when the run ends in success, 1 when it ends otherwise or
    was killed, 2 when there is nothing to watch.
    """
    from rich.console import Console

    from tsa_bench.console.watch import watch as do_watch

    if interval_s <= 0:
        click.echo("error: --interval must be > 0 (s)", err=True)
        sys.exit(EXIT_BAD_INPUT)
    console = Console(force_terminal=None if not plain else False, soft_wrap=plain)
    sys.exit(do_watch(run_file, plain=plain, once=once, interval_s=interval_s, wait_s=wait_s, console=console))
