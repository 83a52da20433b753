"""`tsa-bench lab LAB.yaml`: every rig of a lab file at once, one run file each.

Exit codes as in :mod:`tsa_bench.cli`: 0 every rig's run succeeded; 1 any failed (the
others still ran to their end); 2 the lab file (or a bench or protocol it names) is not
valid, nothing moved; 130 stopped with Ctrl-C or SIGTERM (every file closed "aborted").
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from tsa_bench.cli.exits import EXIT_ABORTED, EXIT_BAD_INPUT, EXIT_FAILED, fail
from tsa_bench.cli.loading import ALLOW_URL, TRUST_FW


@click.command("lab")
@click.argument("lab_file", type=click.Path(dir_okay=False))
@click.option("--out", "out_dir", default="runs", show_default=True, help="Directory for the rigs' run files.")
@click.option("--catalogue", "catalogue_url", default=None, metavar="URL",
              help="Catalogue every rig registers its run in: a database URL (postgresql://user@host/db), a "
                   "SQLite file or 'none' (default: $TSA_BENCH_CATALOGUE, else OUT/catalogue.sqlite).")
@ALLOW_URL
@TRUST_FW
def lab(lab_file: str, out_dir: str, catalogue_url: str | None, allow_url: bool, trust_firmware_dir: bool) -> None:
    """Run every rig of LAB_FILE at once, each in its own process with its own run file.

    The whole lab file is checked first (every problem shown with its file:line); then
    each rig runs as `tsa-bench run` would run it. Operator prompts are asked one at a
    time, naming the rig. Ctrl-C stops every rig safely (STOP, each file closed
    "aborted"); one rig's fault or lost link leaves the others running. A summary per
    rig at the end.
    """
    from tsa_bench.lab.labfile import LabFileError, read_lab
    from tsa_bench.lab.supervisor import Supervisor
    from tsa_bench.shipped import find_config

    found, shipped = find_config(lab_file, "labs")
    if shipped:
        click.echo(f"tsa-bench: {lab_file} is not in the current folder: using the shipped {found}", err=True)
    try:
        the_lab = read_lab(found, allow_url=allow_url, trust_firmware_dir=trust_firmware_dir)
    except LabFileError as exc:
        click.echo(f"error: {found} is not a usable lab file; nothing was run:", err=True)
        for problem in exc.problems:
            click.echo(f"  {problem}", err=True)
        sys.exit(EXIT_BAD_INPUT)
    except KeyboardInterrupt:
        fail("aborted before the lab started; nothing was run", EXIT_ABORTED)
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        fail(f"cannot make the run folder {out}: {exc.strerror or exc}; nothing was run")
    from tsa_bench.cli.catalogue import registration_target

    target = registration_target(catalogue_url, out / "x.h5")
    sup = Supervisor(the_lab, out, catalogue=target if target is not None else "none", allow_url=allow_url,
                     trust_firmware_dir=trust_firmware_dir, out=click.echo)
    taken = sup.taken_paths()
    if taken:
        fail(f"{taken[0]} already exists; run again in a second or choose another --out; nothing was run")
    click.echo(f"tsa-bench lab '{the_lab.name}': {len(the_lab.rigs)} rigs, run files in {out}"
               + (f", catalogue {target}" if target else ""))
    results = sup.run()
    click.echo("")
    click.echo(format_summary(results))
    if sup.interrupted:
        sys.exit(EXIT_ABORTED)
    sys.exit(0 if all(r.exit_code == 0 for r in results) else EXIT_FAILED)


def format_summary(results) -> str:
    """One line per rig: status, samples, lost samples, device time, run file (reason when it did not succeed)."""
    from tsa_bench.console.progress import hms

    width = max([3] + [len(r.rig) for r in results])
    lines = [f"{'rig':<{width}}  {'status':<11} {'exit':>4} {'samples':>9} {'lost':>5} {'device time':>11}  run file"]
    for r in results:
        code = "" if r.exit_code is None else str(r.exit_code)
        device = hms(r.device_time_s) if r.device_time_s is not None else ""
        lost = "" if r.samples_lost is None else str(r.samples_lost)
        line = f"{r.rig:<{width}}  {r.status:<11} {code:>4} {r.samples:>9} {lost:>5} {device:>11}  {r.path}"
        if r.status != "success" and r.reason:
            line += f"\n{'':<{width}}  {r.reason}"
        lines.append(line)
    ok = sum(r.status == "success" for r in results)
    lines.append(f"{ok} of {len(results)} rigs succeeded")
    return "\n".join(lines)
