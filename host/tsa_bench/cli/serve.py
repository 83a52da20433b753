"""`tsa-bench serve`: the lab page in a browser (docs/lab.md, "The page")."""

from __future__ import annotations

import sys

import click

from tsa_bench.cli.exits import fail


@click.command()
@click.option("--runs", "runs_dir", default="runs", show_default=True, type=click.Path(file_okay=False),
              help="Folder whose runs are followed live (every RUN.h5.live in it).")
@click.option("--catalogue", "catalogue_url", default=None, metavar="URL",
              help="Run catalogue to list and search: a database URL (postgresql://user@host/db), a SQLite file, or "
                   "'none' (default: $TSA_BENCH_CATALOGUE, else catalogue.sqlite in --runs). Its running rows are "
                   "followed live too.")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on; only loopback addresses unless --allow-remote.")
@click.option("--port", default=8765, show_default=True, type=click.IntRange(0, 65535),
              help="Port (0: any free one; the URL printed says which).")
@click.option("--allow-remote", is_flag=True, help="Allow an address other machines can reach (the page has no login).")
@click.option("--cache", "cache_dir", default=None, type=click.Path(file_okay=False),
              help="Keep the report figures here across restarts (default: a temporary folder removed at the end).")
def serve(runs_dir: str, catalogue_url: str | None, host: str, port: int, allow_remote: bool,
          cache_dir: str | None) -> None:
    """A local web page: every rig live, the recent runs with search, report figures.

    Reads only the live sidecars and the catalogue, so the recording never waits for it.
    Exit 2 when it cannot start (address refused or in use); 0 after Ctrl-C.
    """
    from tsa_bench.catalogue import default_target
    from tsa_bench.web.server import ServeError, serve as do_serve

    target = None if catalogue_url == "none" else (catalogue_url or default_target(runs_dir))
    try:
        do_serve(runs_dir, target, host=host, port=port, allow_remote=allow_remote, cache_dir=cache_dir,
                 say=lambda text: click.echo(text) or sys.stdout.flush())
    except ServeError as exc:
        fail(str(exc))
    except KeyboardInterrupt:
        pass
