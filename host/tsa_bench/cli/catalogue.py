"""`tsa-bench ls` (the runs, searched in the catalogue) and `tsa-bench catalogue rebuild | check`,
and the registration every recording command shares (`--catalogue`).

Which catalogue: ``--catalogue URL`` (a SQLAlchemy URL such as
``postgresql://lab@db/tsa``, a SQLite file, or ``none`` for no registration), else
``$TSA_BENCH_CATALOGUE``, else ``catalogue.sqlite`` in the folder of the run files.
Registration never fails a command: a catalogue that cannot be written is one warning.

Exit codes as in :mod:`tsa_bench.cli`: ``ls --open`` exits 1 when the run's file is gone;
bad conditions or an unreachable catalogue exit 2.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
from pathlib import Path

import click

from tsa_bench.cli.exits import EXIT_FAILED, fail
from tsa_bench.cli.loading import MAX_MEMORY

NO_CATALOGUE = "none"

CATALOGUE_OPTION = click.option(
    "--catalogue", "catalogue_url", default=None, metavar="URL",
    help="Run catalogue to register the run in: a database URL (postgresql://user@host/db for a shared lab), "
         "a SQLite file, or 'none' (default: $TSA_BENCH_CATALOGUE, else catalogue.sqlite beside the run file).")


def _warn(text: str) -> None:
    click.echo(f"warning: {text}", err=True)


def registration_target(catalogue_url: str | None, run_path: str | Path) -> str | None:
    """The catalogue a run file is registered in, or None for none."""
    from tsa_bench.catalogue import default_target

    if catalogue_url is not None:
        return None if catalogue_url.strip().lower() == NO_CATALOGUE else catalogue_url
    return default_target(Path(run_path).resolve().parent)


def recorder(catalogue_url: str | None, run_path: Path, *, kind: str, load_g: float | None):
    """The run consumer that registers this run, or None (``--catalogue none``)."""
    target = registration_target(catalogue_url, run_path)
    if target is None:
        return None
    from tsa_bench.catalogue.recorder import CatalogueRecorder

    return CatalogueRecorder(target, run_path, kind=kind, load_g=load_g, warn=_warn)


def register_file(catalogue_url: str | None, run_path: str | Path) -> None:
    """Register a finished run file from its content (import); a failure is a warning."""
    target = registration_target(catalogue_url, run_path)
    if target is None:
        return
    from tsa_bench.catalogue import CatalogueError, open_catalogue, shown_url
    from tsa_bench.catalogue.runfiles import file_facts

    try:
        with open_catalogue(target) as cat:
            cat.upsert(file_facts(run_path))
    except (CatalogueError, OSError, ValueError) as exc:
        _warn(f"catalogue {shown_url(target)}: {exc}; {run_path} is complete (register it later: "
              f"tsa-bench catalogue rebuild {Path(run_path).resolve().parent})")


def register_verdict(catalogue_url: str | None, run_paths: list[str], verdict: str, detail: str) -> None:
    """Record a diagnose verdict on each run's row (registering a run not yet there); failures warn."""
    from tsa_bench.catalogue import CatalogueError, open_catalogue, shown_url
    from tsa_bench.catalogue.runfiles import file_facts

    for path in run_paths:
        target = registration_target(catalogue_url, path)
        if target is None:
            continue
        try:
            with open_catalogue(target) as cat:
                if cat.set_verdict(path, verdict, detail) is None:
                    cat.upsert(file_facts(path))
                    cat.set_verdict(path, verdict, detail)
        except (CatalogueError, OSError, ValueError) as exc:
            _warn(f"catalogue {shown_url(target)}: the verdict of {path} is not registered: {exc}")


# -- ls ------------------------------------------------------------------------------
def _local(when) -> str:
    import datetime as dt

    if when is None:
        return ""
    return when.replace(tzinfo=dt.timezone.utc).astimezone().strftime("%Y-%m-%d %H:%M")


def _shown_status(row) -> tuple[str, str]:
    """(status, note) as the file says now."""
    from tsa_bench.store.live import recording

    state = row.file_state()
    if state == "running":
        return ("recording", "being recorded (tsa-bench watch shows it)") if recording(row.path) else (
            "killed", "its recording process is gone: tsa-bench catalogue rebuild reads the file again")
    note = {"missing": "FILE MISSING", "changed": "FILE CHANGED since it was registered: tsa-bench catalogue "
            "rebuild reads it again", "elsewhere": f"on host {row.host}"}.get(state, "")
    return row.status, note


def _row_line(row) -> str:
    from tsa_bench.console.progress import hms

    status, note = _shown_status(row)
    segs = "" if row.segments_done is None else f"{row.segments_done}" + (
        f"/{row.n_segments}" if row.n_segments is not None else "")
    load = "" if row.load_g is None else f"{row.load_g:g}"
    dur = hms(row.device_time_s) if row.device_time_s is not None else ""
    notes = [n for n in (note, f"verdict {row.verdict}" if row.verdict else "") if n]
    return (f"{status:<9} {row.id:>5} {_local(row.started):<16} {dur:>9} {row.samples or 0:>9} {row.samples_lost or 0:>5} "
            f"{segs:>9}  {(row.plan or '')[:24]:<24} {(row.rig or '')[:10]:<10} {(row.sample or '')[:8]:<8} "
            f"{load:>7}  {row.name}" + (f"  ({'; '.join(notes)})" if notes else ""))


HEADER = (f"{'status':<9} {'id':>5} {'started':<16} {'duration':>9} {'samples':>9} {'lost':>5} {'segments':>9}  "
          f"{'plan':<24} {'rig':<10} {'sample':<8} {'load_g':>7}  file")


def _file_line(line) -> str:
    from tsa_bench.console.progress import hms

    if line.problem and line.status in ("?", "recording"):
        return f"{line.status:<9} {'-':>5} {'':<16} {'':>9} {'':>9} {'':>5} {'':>9}  {'':<24} {'':<10} {'':<8} " \
               f"{'':>7}  {line.path.name}  ({line.problem})"
    return (f"{line.status:<9} {'-':>5} {line.created[:16].replace('T', ' '):<16} {hms(line.duration_s):>9} "
            f"{line.samples:>9} {'':>5} {line.segments:>9}  {line.plan[:24]:<24} {'':<10} {'':<8} {'':>7}  "
            f"{line.path.name}  (not in the catalogue" + (f"; {line.link}" if line.link else "") + ")")


def _open_for_ls(folder: str | None, catalogue_url: str | None):
    """(catalogue, folder filter, temporary file or None) for ls."""
    from tsa_bench.catalogue import CATALOGUE_FILE, ENV_VAR, CatalogueError, open_catalogue

    given = catalogue_url or os.environ.get(ENV_VAR)
    try:
        if given:
            return open_catalogue(given), folder, None
        where = Path(folder or "runs")
        if (where / CATALOGUE_FILE).is_file():
            return open_catalogue(where / CATALOGUE_FILE), str(where), None
    except CatalogueError as exc:
        fail(str(exc))
    return None, str(folder or "runs"), None


def _from_files(folder: str):
    """A throw-away catalogue of the folder's files (no catalogue there), for a search."""
    from tsa_bench.catalogue import open_catalogue
    from tsa_bench.catalogue.rebuild import rebuild

    tmp = tempfile.NamedTemporaryFile(suffix=".sqlite", delete=False)
    tmp.close()
    cat = open_catalogue(tmp.name)
    rebuild(cat, folder, with_hash=False)
    return cat, tmp.name


@click.command("ls")
@click.argument("folder", type=click.Path(file_okay=False), required=False)
@click.option("--catalogue", "catalogue_url", default=None, metavar="URL",
              help="Catalogue to read (default: $TSA_BENCH_CATALOGUE, else FOLDER/catalogue.sqlite).")
@click.option("--where", "wheres", multiple=True, metavar="FIELD OP VALUE",
              help="Only runs where FIELD OP VALUE holds (repeatable, all must hold): sample=S3, load_g>=200, "
                   "plan~lifetime, rig!=B; OP is = != < <= > >= or ~ (contains); any other name is a --meta key.")
@click.option("--status", "statuses", multiple=True,
              type=click.Choice(["success", "aborted", "failed", "running", "killed"]),
              help="Only runs that ended so (repeatable).")
@click.option("--since", default=None, metavar="DATE", help="Only runs started on or after DATE (2026-11-01, local).")
@click.option("--until", default=None, metavar="DATE", help="Only runs started before DATE.")
@click.option("--limit", type=click.IntRange(1), default=None, help="At most this many (the newest).")
@click.option("--json", "as_json", is_flag=True, help="A JSON list of objects, one per run, instead of the table.")
@click.option("--open", "open_id", type=int, default=None, metavar="ID", help="Print the path of run ID and stop.")
@MAX_MEMORY
def ls_cmd(folder: str | None, catalogue_url: str | None, wheres: tuple[str, ...], statuses: tuple[str, ...],
           since: str | None, until: str | None, limit: int | None, as_json: bool, open_id: int | None) -> None:
    """The runs of FOLDER (default runs/) from its catalogue, oldest first: status, id, start, duration,
    samples, lost samples, segments, plan, rig, sample, load; a row whose file is missing or changed
    says so, and run files the catalogue does not hold are listed too. Without a catalogue the
    files are listed (and searched) directly."""
    from tsa_bench.catalogue import CatalogueError, WhereError

    cat, where, tmp = _open_for_ls(folder, catalogue_url)
    searching = bool(wheres or statuses or since or until or limit or as_json or open_id is not None)
    if cat is None:
        if not Path(where).is_dir():
            fail(f"{where}: no such folder")
        if not searching:
            _plain_listing(where)
            return
        click.echo(f"note: no catalogue in {where}: searching its files (tsa-bench catalogue rebuild {where} makes "
                   "one, and searches then take milliseconds)", err=True)
        cat, tmp = _from_files(where)
    try:
        if open_id is not None:
            _open_run(cat, open_id)
            return
        try:
            rows = cat.search(wheres, status=statuses or None, since=since, until=until, limit=limit,
                              folder=where if (folder or not catalogue_url) and not tmp else None)
        except WhereError as exc:
            fail(str(exc))
        except CatalogueError as exc:
            fail(str(exc))
        rows.reverse()
        extra = [] if searching else _unregistered(where, rows)
        if as_json:
            click.echo(json.dumps([{**r.as_dict(), "file_state": r.file_state()} for r in rows], indent=1))
            return
        if not rows and not extra:
            click.echo("no runs match" if searching else f"no runs in {where}")
            return
        click.echo(HEADER)
        for r in rows:
            click.echo(_row_line(r))
        for line in extra:
            click.echo(_file_line(line))
    finally:
        cat.close()
        if tmp:
            os.unlink(tmp)


def _unregistered(folder: str, rows) -> list:
    """Listing lines of the run files in the folder that no row holds."""
    from tsa_bench.catalogue.rebuild import run_files
    from tsa_bench.store.listing import run_line

    known = {r.path for r in rows}
    return [run_line(p) for p in run_files(folder) if str(p.resolve()) not in known]


def _plain_listing(folder: str) -> None:
    from tsa_bench.console.progress import hms
    from tsa_bench.store.listing import list_runs

    rows = list_runs(folder)
    if not rows:
        click.echo(f"no run files (*.h5) in {folder}")
        return
    click.echo(f"{'status':<10} {'duration':>9} {'samples':>9} {'segments':>11}  {'plan':<28} file")
    for r in rows:
        if r.problem and r.status in ("?", "recording"):
            click.echo(f"{r.status:<10} {'':>9} {'':>9} {'':>11}  {'':<28} {r.path.name}  ({r.problem})")
            continue
        click.echo(f"{r.status:<10} {hms(r.duration_s):>9} {r.samples:>9} {r.segments:>11}  {r.plan:<28} "
                   f"{r.path.name}" + (f"  ({r.link})" if r.link else ""))


def _open_run(cat, run_id: int) -> None:
    row = cat.get(run_id)
    if row is None:
        fail(f"no run {run_id} in the catalogue")
    state = row.file_state()
    if state == "missing":
        fail(f"run {run_id}: its file {row.path} is missing", EXIT_FAILED)
    if state == "elsewhere":
        click.echo(f"note: run {run_id} was recorded on host {row.host}", err=True)
    if state == "changed":
        click.echo(f"warning: run {run_id}: {row.path} changed since it was registered", err=True)
    click.echo(row.path)


# -- catalogue rebuild | check ------------------------------------------------------------
@click.group("catalogue")
def catalogue_cmd() -> None:
    """The run catalogue: rebuild it from the run files, check it against them."""


@catalogue_cmd.command("rebuild")
@click.argument("folder", type=click.Path(file_okay=False, exists=True))
@click.option("--catalogue", "catalogue_url", default=None, metavar="URL",
              help="Catalogue to write (default: $TSA_BENCH_CATALOGUE, else FOLDER/catalogue.sqlite).")
def rebuild_cmd(folder: str, catalogue_url: str | None) -> None:
    """Register every run file in FOLDER from the file itself (the files are the truth)."""
    from tsa_bench.catalogue import CatalogueError, default_target, open_catalogue, shown_url
    from tsa_bench.catalogue.rebuild import rebuild

    target = catalogue_url or default_target(folder)
    try:
        with open_catalogue(target) as cat:
            report = rebuild(cat, folder)
    except CatalogueError as exc:
        fail(str(exc))
    except KeyboardInterrupt:
        fail("interrupted; the rows written so far stay (run it again to finish)", 130)
    for path, why in report.unreadable:
        click.echo(f"skipped {path}: {why}", err=True)
    for row in report.changed:
        click.echo(f"changed since registered: {row.path} (run {row.id}): its row now says what the file says",
                   err=True)
    for row in report.missing:
        click.echo(f"missing: run {row.id} {row.path} is in the catalogue but its file is gone", err=True)
    click.echo(f"{report.files} run files registered in {shown_url(target)} ({report.added} new, {report.updated} "
               f"updated; {len(report.unreadable)} skipped, {len(report.missing)} missing)")


@catalogue_cmd.command("check")
@click.argument("folder", type=click.Path(file_okay=False), required=False)
@click.option("--catalogue", "catalogue_url", default=None, metavar="URL",
              help="Catalogue to check (default: $TSA_BENCH_CATALOGUE, else FOLDER/catalogue.sqlite).")
@click.option("--verify", is_flag=True, help="Also compare every file's SHA-256 (reads every file).")
def check_cmd(folder: str | None, catalogue_url: str | None, verify: bool) -> None:
    """List the rows whose run file is missing or changed; exit 1 if there is any."""
    from tsa_bench.catalogue import CatalogueError, default_target, open_catalogue
    from tsa_bench.catalogue.rebuild import check

    target = catalogue_url or default_target(folder or "runs")
    if "://" not in target and not Path(target).is_file():
        fail(f"no catalogue at {target} (tsa-bench catalogue rebuild {folder or 'runs'} makes one)")
    try:
        with open_catalogue(target) as cat:
            bad = check(cat, folder, verify=verify)
    except CatalogueError as exc:
        fail(str(exc))
    for row, state in bad:
        click.echo(f"{state:<8} run {row.id} {row.path}")
    click.echo(f"{len(bad)} row(s) whose file is missing or changed" if bad else "every run file is as registered")
    sys.exit(EXIT_FAILED if bad else 0)
