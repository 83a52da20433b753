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
