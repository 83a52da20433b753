"""`tsa-bench run --resume RUN.h5`: what the resumed run needs, read from the first run.

The protocol is the one RUN.h5 stored (compiled again); the bench is ``--bench`` when
given, else the bench text RUN.h5 stored. A killed run is first finished from its live
journal (:mod:`tsa_bench.store.recover`); a run file that cannot be read is rebuilt from
its journal into a new file, which the resumed run then continues. Exits 2 with one line
when it cannot resume.
"""

from __future__ import annotations

import atexit
import os
import tempfile
from pathlib import Path

import click

from tsa_bench.cli.exits import fail
from tsa_bench.cli.loading import load_bench_or_exit


def _stored_bench(run, resume_file: str, allow_url: bool, trust_firmware_dir: bool):
    """The bench text the first run stored, as a file (the simulated bench reads a path)."""
    from tsa_bench.bench import BenchConfigError, parse_bench

    where = f"{resume_file}:/config/bench"
    try:
        parse_bench(run.bench_text, where, allow_url=allow_url, trust_firmware_dir=trust_firmware_dir)
    except BenchConfigError as exc:
        fail(f"the bench stored in {resume_file} cannot be used ({exc}); give --bench")
    fd, name = tempfile.mkstemp(prefix="tsa-bench-resume-", suffix=".yaml")
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(run.bench_text)
    atexit.register(lambda: Path(name).unlink(missing_ok=True))
    return parse_bench(run.bench_text, name, allow_url=allow_url, trust_firmware_dir=trust_firmware_dir), name


def _protocol_path(run_file: str) -> str:
    """The path the first run's protocol was read from (its /config/protocol attribute)."""
    import h5py

    try:
        with h5py.File(run_file, "r") as f:
            value = f["config/protocol"].attrs.get("path", "")
    except (OSError, KeyError, RuntimeError):
        return ""
    return value.decode(errors="replace") if isinstance(value, bytes) else str(value)


def _stored_variables(run) -> dict | None:
    """The protocol variables the run was given (``run --set``), kept in its metadata."""
    import json

    meta = run.attrs.get("metadata")
    try:
        meta = json.loads(meta) if isinstance(meta, (str, bytes)) else meta
    except ValueError:
        return None
    found = meta.get("protocol_variables") if isinstance(meta, dict) else None
    return found if isinstance(found, dict) else None


def prepare_resume(resume_file: str, bench_path: str | None, port: str | None, allow_url: bool,
                   trust_firmware_dir: bool):
    """(bench, plan, ResumePoint, bench file path, the protocol variables it was given, the run
    file resumed) for resuming ``resume_file`` (the file resumed is a new one when
    ``resume_file`` had to be rebuilt)."""
    from tsa_bench.plan import PlanErrors, load_plan_text
    from tsa_bench.runner.commands import plan_problems
    from tsa_bench.runner.resume import CannotResume, resume_point
    from tsa_bench.store import RunFileError, read_run
    from tsa_bench.store.live import sidecar_path
    from tsa_bench.store.recover import RecoveryError, recover_run

    try:
        try:
            run = read_run(resume_file)
        except RunFileError:
            if not sidecar_path(resume_file).is_file():
                raise
            run = None   # killed inside a flush: rebuilt from its journal below
        if run is None or run.exit_status == "running":
            rec = recover_run(resume_file)
            if rec.rebuilt:
                click.echo(f"tsa-bench: {rec.message}; resuming {rec.path}", err=True)
                resume_file = str(rec.path)
            else:
                click.echo(f"tsa-bench: {resume_file} was killed while recording; {rec.samples} samples after its "
                           "last flush were recovered from its live sidecar", err=True)
            run = read_run(resume_file)
    except (RunFileError, RecoveryError) as exc:
        fail(str(exc))
    if not run.protocol_text.strip():
        fail(f"{resume_file} stores no protocol (an imported run?); there is nothing to resume")
    if bench_path is not None or not run.bench_text.strip():
        bench = load_bench_or_exit(bench_path, port, allow_url=allow_url, trust_firmware_dir=trust_firmware_dir)
        bench_file = bench.path
    else:
        bench, bench_file = _stored_bench(run, resume_file, allow_url, trust_firmware_dir)
    # the name the first run's segment sources carry, so both files name the same lines
    source = f"{resume_file}:/config/protocol"
    stored_path = _protocol_path(resume_file)
    if stored_path:
        source = Path(stored_path).name
    elif run.segments is not None and len(run.segments):
        first = run.segments["source"][0]
        first = first.decode(errors="replace") if isinstance(first, bytes) else str(first)
        if ":" in first:
            source = first.rsplit(":", 1)[0]
    try:
        variables = _stored_variables(run)
        plan = load_plan_text(run.protocol_text, bench.limits, source, variables)
    except PlanErrors as exc:
        fail(f"the protocol stored in {resume_file} does not compile on bench '{bench.name}':\n{exc}")
    problems = plan_problems(plan, bench.steps_per_turn)
    if problems:
        fail(f"the protocol stored in {resume_file} cannot be sent to bench '{bench.name}':\n" + "\n".join(problems))
    try:
        point = resume_point(run, plan, resume_file)
    except CannotResume as exc:
        fail(str(exc))
    click.echo(f"tsa-bench: {point.describe()}", err=True)
    return bench, plan, point, bench_file, variables, resume_file
