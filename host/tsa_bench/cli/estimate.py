"""`tsa-bench estimate`: load and strain from resistance and twist (fit a model, or apply one to a run)."""

from __future__ import annotations

import click

from tsa_bench.cli.exits import check_output, fail, unwritable_reason
from tsa_bench.cli.loading import FORCE, MAX_MEMORY


@click.command("estimate")
@click.argument("run", required=False, type=click.Path(dir_okay=False))
@click.option("--model", "model_file", type=click.Path(dir_okay=False), default=None,
              help="A load-strain model JSON (from --train) to estimate RUN with.")
@click.option("--train", multiple=True, type=click.Path(dir_okay=False),
              help="Training run at known loads (repeatable; two or more loads in all): fit a model.")
@click.option("--out", "out", type=click.Path(dir_okay=False), default=None,
              help="With --train: where to write the model JSON.")
@MAX_MEMORY
@FORCE
def estimate(run: str | None, model_file: str | None, train: tuple[str, ...], out: str | None, force: bool) -> None:
    """Estimate load (N) and strain from resistance and twist, with one-sigma uncertainty.

    tsa-bench estimate --train RUN1.h5 [--train RUN2.h5] --out M.json   fits the model;
    tsa-bench estimate RUN.h5 --model M.json   prints per-hold estimates and, where the run
    recorded them, their errors against the declared load and the position sensor (which the
    estimate never reads). docs/control.md.
    """
    from tsa_bench.models import load_strain as ls
    from tsa_bench.outputs import OutputExists
    from tsa_bench.store.reader import RunFileError, read_run

    def _read(path: str):
        try:
            return read_run(path)
        except RunFileError as exc:
            fail(str(exc))

    if train:
        if run or model_file:
            fail("--train fits a model; give RUN and --model only to estimate")
        if not out:
            fail("--train needs --out M.json (where to write the model)")
        why = unwritable_reason(out)
        if why:
            fail(f"{out}: cannot write the model file there ({why})")
        check_output(out, force)
        try:
            model = ls.fit([_read(p) for p in train])
            ls.save(model, out)
        except (ls.LoadStrainError, OutputExists) as exc:
            fail(str(exc))
        except OSError as exc:
            fail(f"{out}: cannot write the model file ({exc.strerror or exc})")
        click.echo(f"load-strain model from {len(train)} run(s): loads {model.load_range_N[0]:.3g}.."
                   f"{model.load_range_N[1]:.3g} N, twist {model.twist_range_turns[0]:g}..{model.twist_range_turns[1]:g} "
                   f"turns; scatter {model.sd_length_mm:.3g} mm, {model.sd_resistance_ohm:.3g} ohm")
        click.echo(f"model written to {out}")
        return
    if not run or not model_file:
        fail("give RUN and --model M.json to estimate, or --train RUN.h5 --out M.json to fit")
    try:
        model = ls.load(model_file)
    except ls.LoadStrainError as exc:
        fail(str(exc))
    data = _read(run)
    try:
        est = ls.estimate(model, data)
        rows = ls.hold_table(est, data)
    except ls.LoadStrainError as exc:
        fail(str(exc))
    click.echo(f"{'t_s':>8} {'turns':>7} {'load_N':>8} {'+-':>6} {'strain_%':>9} {'+-':>6} {'length_mm':>9} "
               f"{'load_err_%':>10} {'length_err_mm':>13}")
    for r in rows:
        click.echo(f"{r['t_s']:8.1f} {r['turns']:7.2f} {r['load_N']:8.3f} {r['load_sd_N']:6.3f} "
                   f"{100 * r['strain']:9.3f} {100 * r['strain_sd']:6.3f} {r['length_mm']:9.2f} "
                   f"{r['load_err_percent']:10.2f} {r['length_err_mm']:13.2f}")
    summary = ls.summary(est, data)
    click.echo(f"estimated at {summary['n']} settled samples of {len(data)}")
    if summary.get("load_err_max_percent") is not None:
        click.echo(f"load error vs the declared load: max {summary['load_err_max_percent']:.2f} %, mean "
                   f"{summary['load_err_mean_percent']:.2f} % (samples more than {model.window_s:g} s after a load change)")
        click.echo(f"length error vs the position sensor: max {summary['length_err_max_mm']:.3f} mm = "
                   f"{summary['length_err_max_percent']:.3f} % of length (same samples)")
