"""`tsa-bench reproduce`: every thesis measurement against the calibrated simulated bench.

Exit codes: 0 the table was produced (whatever it says); 2 bad input (a record file or
the calibration plan is invalid: every problem with file:line:col).
"""

from __future__ import annotations

import json
import sys
import time

import click

from tsa_bench.cli.exits import check_output_folder, fail, unwritable_reason
from tsa_bench.cli.loading import FORCE


#: what each role's count means, printed beside it
ROLE_NOTES = {"held-out": "  <- the evidence", "fitted": "  (calibrated to these: not evidence)",
              "derived": "  (computed from fitted rows: shown, never counted)",
              "duplicate": "  (the same error as another row in % or absolute: counted once, with it)",
              "qualitative": "  (directions, or true by construction: not counted as agreement)",
              "uninformative": "  (tolerance wider than the quantity's range: shown, never counted)"}


def _num(v: float | None) -> str:
    return "-" if v is None else f"{v:.4g}"


@click.command("reproduce")
@click.option("--quick", is_flag=True, help="Shortened experiments (fewer cycles, shorter holds) for a fast check.")
@click.option("--json", "as_json", is_flag=True, help="Print the rows and the summary as JSON instead of the table.")
@click.option("--figures", "figures_dir", type=click.Path(file_okay=False), default=None,
              help="Write one figure per thesis chapter (chapterN.png) into this directory.")
@click.option("--records", "records_dir", type=click.Path(file_okay=False), default=None,
              help="Directory of record files (default: configs/thesis/).")
@click.option("--plan", "plan_file", type=click.Path(dir_okay=False), default=None,
              help="Calibration plan (default: configs/thesis/calibration.yaml).")
@click.option("--chapter", type=int, default=None, help="Only the records of this thesis chapter.")
@click.option("--seed", type=int, default=0, show_default=True, help="First noise seed of the simulated runs.")
@click.option("--seeds", "n_seeds", type=click.IntRange(min=1), default=5, show_default=True,
              help="Number of noise seeds (seed, seed+1, ...); a row agrees when at least 80 % of them agree.")
@FORCE
def reproduce(quick: bool, as_json: bool, figures_dir: str | None, records_dir: str | None, plan_file: str | None,
              chapter: int | None, seed: int, n_seeds: int, force: bool) -> None:
    """Run each thesis experiment on its simulated preset and print thesis vs simulated, gap and verdict.

    Each experiment runs once per noise seed. Verdicts: agrees (at least 80 % of the seeds
    within the thesis's own spread, widened where the seed scatter is wider), disagrees
    (with the named reason), consistency-only (the simulator was built from that number),
    not simulated (why); "unstable" marks rows whose seeds disagree among themselves.
    Roles: fitted, held-out (the evidence), derived (computed from a fitted row),
    duplicate (the same error in % and absolute), qualitative (a direction, or true by
    construction), uninformative (tolerance wider than the quantity's range), built-from.
    See docs/thesis-records.md.
    """
    from tsa_bench.reproduce.experiments import Lab
    from tsa_bench.reproduce.plan import plan_or_empty
    from tsa_bench.reproduce.records import RecordsError, load_records, record_files
    from tsa_bench.reproduce.table import evaluate, summary

    t0 = time.perf_counter()
    try:
        files = record_files(records_dir) if records_dir is not None else None
        if files is not None and not files:
            fail(f"{records_dir}: no record files (*.yaml)")
        records = load_records(files)
        plan = plan_or_empty(records, plan_file)
    except RecordsError as exc:
        fail(str(exc))
    if chapter is not None:
        records = [r for r in records if r.chapter == chapter]
        if not records:
            fail(f"no records of chapter {chapter}")
    why = unwritable_reason(figures_dir) if figures_dir is not None else None
    if why:   # before the experiments run, not after them
        fail(f"{figures_dir}: cannot write the figures there ({why})")
    check_output_folder(figures_dir, force)
    from tsa_bench.models.long_run_fits import one_blas_thread

    seeds = list(range(seed, seed + n_seeds))
    with one_blas_thread():   # small least squares: BLAS threads cost CPU and change rounding with the core count
        rows = evaluate(records, [Lab(seed=s, quick=quick) for s in seeds], plan)
    summ = summary(rows)
    summ["quick"] = quick
    summ["seeds"] = seeds
    summ["seconds"] = round(time.perf_counter() - t0, 1)
    if figures_dir is not None:
        from tsa_bench.reproduce.figures import write_figures

        from tsa_bench.outputs import OutputExists

        try:
            written = write_figures(records, rows, figures_dir)
        except OutputExists as exc:
            fail(str(exc))
        except OSError as exc:
            fail(f"{exc.filename or figures_dir}: cannot write the figure ({exc.strerror or exc})")
        for path in written:
            click.echo(f"wrote {path}", err=as_json)
    if as_json:
        click.echo(json.dumps({"rows": [r.as_dict() for r in rows], "summary": summ}, indent=1))
        return
    head = f"{'record':36s} {'thesis':>26s} {'simulated':>11s} {'+-seeds':>9s} {'gap %':>7s} {'tolerance':>20s} " \
           f"{'agree':>5s} {'verdict':>16s} {'role':>13s}  reason / source"
    current = None
    n = len(seeds)
    for r in rows:
        if r.chapter != current:
            current = r.chapter
            click.echo(f"\nchapter {current}\n{head}")
        gp = "-" if r.gap_percent is None else f"{r.gap_percent:+.0f}"
        frac = "-" if r.agree_fraction is None else f"{round(r.agree_fraction * n)}/{n}"
        verdict = r.verdict + ("*" if r.unstable else "")
        tail = r.reason if r.reason else r.source
        click.echo(f"{r.id:36s} {r.thesis:>26s} {_num(r.simulated):>11s} {_num(r.spread):>9s} {gp:>7s} "
                   f"{r.tolerance:>20s} {frac:>5s} {verdict:>16s} {r.role:>13s}  {tail}")
    v = summ["by_verdict"]
    click.echo(f"\n{summ['records']} records, seeds {seeds[0]}-{seeds[-1]} (a row agrees when >= 80 % of its seeds "
               f"agree; * unstable: its seeds disagree among themselves): {v['consistency-only']} consistency-only "
               f"(built-from), {v['not simulated']} not simulated, {v['not computed']} not computed")
    for role, c in summ["by_role"].items():
        click.echo(f"  {role + ':':14s} {c['agrees']} agree, {c['disagrees']} disagree ({c['unstable']} unstable)"
                   f"{ROLE_NOTES.get(role, '')}")
    for kind, c in sorted(summ["held_out_by_kind"].items()):
        what = "measured quantities" if kind == "quantity" else "model coefficients and parameters (Tables 3.1-3.3)"
        click.echo(f"  held-out {what}: {c['agrees']} agree, {c['disagrees']} disagree")
    if summ["unexplained_disagreements"]:
        click.echo("disagreements without a named reason: " + ", ".join(summ["unexplained_disagreements"]))
    click.echo(f"({summ['seconds']} s{', quick experiments' if quick else ''})")
    sys.stdout.flush()
