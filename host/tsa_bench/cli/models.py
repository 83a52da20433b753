"""Model commands: `tsa-bench fit | predict | manipulator`: the thesis's models on run files (docs/models.md).

Exit codes: 0 success; 2 bad input (missing or unreadable file, unknown model, run
lacking a needed column, bad YAML), with one ``error: <file>: <what>`` line.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from tsa_bench.cli.exits import EXIT_BAD_INPUT

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table

# The names of tsa_bench.models.saved.MODEL_NAMES, here so that --help does not import the models.
MODEL_NAMES = ("preisach", "polynomial", "strain-resistance", "self-sensing")


def _fail(msg: str) -> None:
    click.echo(f"error: {msg}", err=True)
    sys.exit(EXIT_BAD_INPUT)


def _read(paths: tuple[str, ...] | list[str]):
    from tsa_bench.store.reader import RunFileError, read_run

    out = []
    for p in paths:
        try:
            out.append(read_run(p))
        except RunFileError as exc:
            _fail(str(exc))
    return out


def _console() -> Console:
    """A rich console; wide when not a terminal (pipes, tests) so no column is cut."""
    from rich.console import Console

    console = Console()
    return console if console.is_terminal else Console(width=160)


def _metrics_table(title: str, rows: list[tuple[str, str, dict[str, Any]]]) -> Table:
    from rich.table import Table

    table = Table(title=title)
    for col in ("set", "run", "n", "E_aver", "sigma", "max |e|", "mean % (3.21)", "max % (3.21)"):
        table.add_column(col, justify="right" if col not in ("set", "run") else "left")
    for kind, path, m in rows:
        u = m["unit"]
        table.add_row(kind, Path(path).name, str(m["n"]), f"{m['e_aver']:.4g} {u}", f"{m['sigma']:.4g} {u}",
                      f"{m['max_abs']:.4g} {u}", f"{m['mean_percent']:.4f}", f"{m['max_percent']:.4f}")
    return table


@click.command("fit")
@click.argument("model", type=click.Choice(MODEL_NAMES))
@click.argument("runs", nargs=-1, required=True)
@click.option("--input", "input_col", default=None,
              help="Input column (preisach/polynomial; default turns): any numeric sample column, e.g. "
                   "heater_voltage, resistance or an extra channel such as temperature.")
@click.option("--output", "output_col", default=None,
              help="Output column (preisach/polynomial; default length): any other numeric column, e.g. strain.")
@click.option("--validate", "validate", multiple=True, help="Run file to validate on (repeatable).")
@click.option("--levels", default=20, show_default=True, help="Preisach discretisation M.")
@click.option("--load-g", "load_g", type=float, default=None,
              help="preisach/polynomial: fit and score only the samples at this declared load (g).")
@click.option("--out", "out", required=True, type=click.Path(dir_okay=False), help="Model JSON to write.")
def fit_cmd(model: str, runs: tuple[str, ...], input_col: str | None, output_col: str | None,
            validate: tuple[str, ...], levels: int, load_g: float | None, out: str) -> None:
    """Identify MODEL on RUNS; print identification/validation metrics; save the model JSON."""
    from tsa_bench.models.fitting import FitError, fit, fit_notes
    from tsa_bench.models.saved import ModelFileError, save_model

    train = _read(runs)
    val = _read(validate)
    try:
        saved = fit(model, train, input_col, output_col, val, levels=levels, load_g=load_g)
    except (FitError, ModelFileError) as exc:
        _fail(str(exc))
    for note in fit_notes(saved, train):
        click.echo(f"note: {note}", err=True)
    save_model(saved, out)
    rows = [("identification", p, m) for p, m in saved.metrics["identification"].items()]
    rows += [("validation", p, m) for p, m in saved.metrics["validation"].items()]
    _console().print(_metrics_table(f"{model}: {saved.input['column']} -> {saved.output['column']}", rows))
    click.echo(f"model written to {out}")


@click.command("predict")
@click.argument("model_file", type=click.Path(dir_okay=False))
@click.argument("run", type=click.Path(dir_okay=False))
@click.option("--write-prediction", is_flag=True,
              help="Write the prediction into RUN as /samples/predicted_<output> (beside the measurement).")
def predict_cmd(model_file: str, run: str, write_prediction: bool) -> None:
    """Print the metrics of MODEL_FILE on RUN; optionally store the prediction in the run file."""
    import h5py

    from tsa_bench.models.fitting import FitError, evaluate
    from tsa_bench.models.saved import ModelFileError, load_model_file

    try:
        saved = load_model_file(model_file)
    except ModelFileError as exc:
        _fail(str(exc))
    data = _read([run])[0]
    try:
        pred, metrics = evaluate(saved, data)
    except (FitError, ModelFileError) as exc:
        _fail(str(exc) if str(exc).startswith(run) else f"{model_file}: {exc}")
    _console().print(_metrics_table(f"{saved.model} ({Path(model_file).name}): "
                                   f"{saved.input['column']} -> {saved.output['column']}",
                                   [("prediction", run, metrics)]))
    if write_prediction:
        name = f"predicted_{saved.output['column']}"
        with h5py.File(run, "a") as f:
            g = f["samples"]
            if name in g:
                del g[name]
            ds = g.create_dataset(name, data=pred)
            ds.attrs["units"] = saved.output["unit"]
            ds.attrs["model_file"] = str(model_file)
        click.echo(f"prediction written to {run}:/samples/{name}")


def _manipulator_config(path: str) -> dict[str, Any]:
    import yaml

    p = Path(path)
    if not p.exists():
        _fail(f"{p}: no such file")
    try:
        doc = yaml.safe_load(p.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        _fail(f"{p}: not valid YAML ({exc})")
    if not isinstance(doc, dict) or not isinstance(doc.get("geometry"), dict):
        _fail(f"{p}: needs a 'geometry' mapping {{l0_m, r_m, w0_m}}")
    return doc


@click.command("manipulator")
@click.argument("config", type=click.Path(dir_okay=False))
def manipulator_cmd(config: str) -> None:
    """Bending angle, velocity models and P-control simulation of the soft manipulator (section 4.2)."""
    import numpy as np
    from rich.table import Table

    from tsa_bench.models.manipulator import (ManipulatorGeometry, bending_angle, simulate_p_control,
                                              velocity_models)
    from tsa_bench.models.tsa_kinematics import TWO_PI

    doc = _manipulator_config(config)
    try:
        geom = ManipulatorGeometry(**{k: float(v) for k, v in doc["geometry"].items()})
        tw = doc.get("twist", {})
        turns = np.linspace(float(tw.get("min_turns", 3)), float(tw.get("max_turns", 18)), int(tw.get("points", 16)))
        vel = doc.get("velocity", {})
        ctl = doc.get("control", {})
    except (TypeError, ValueError) as exc:
        _fail(f"{config}: {exc}")
    console = _console()
    theta = np.degrees(bending_angle(turns * TWO_PI, geom))
    theta_c = np.degrees(bending_angle(turns * TWO_PI, geom, radius_growth=False))
    t = Table(title="bending angle (eq. 4.8)")
    for c in ("turns", "theta (radius growth) deg", "theta (constant radius) deg"):
        t.add_column(c, justify="right")
    for a, b, c in zip(turns, theta, theta_c):
        t.add_row(f"{a:.2f}", f"{b:.2f}", f"{c:.2f}")
    console.print(t)
    click.echo(f"bending range {theta[-1] - theta[0]:.2f} deg over {turns[0]:g}-{turns[-1]:g} turns")
    rate = float(vel.get("rate_hz", 53.9))
    dur = float(vel.get("duration_s", 7.5))
    speed = float(vel.get("motor_rev_per_s", 1.90))
    t0 = float(vel.get("initial_turns", 3.0))
    time_s = np.arange(0.0, dur, 1.0 / rate)
    tw_rad = (t0 + speed * time_s) * TWO_PI
    try:
        models = velocity_models(tw_rad, geom, rate)
    except ValueError as exc:
        _fail(f"{config}: velocity: {exc}")
    if not np.isfinite(models["theta_rad"]).all():
        _fail(f"{config}: velocity: the twist exceeds full contraction (T w >= L0); shorten duration_s")
    vt = Table(title=f"bending velocity models at {speed} rev/s (eqs. 4.9, 4.12, 4.23), deg/s")
    for c in ("t s", "theta deg", "complete", "conventional", "linearised"):
        vt.add_column(c, justify="right")
    for i in np.linspace(151, len(time_s) - 152, 6).astype(int):
        vt.add_row(f"{time_s[i]:.1f}", f"{np.degrees(models['theta_rad'][i]):.2f}",
                   *(f"{np.degrees(models[k][i]):.3f}" for k in ("complete", "conventional", "linearised")))
    console.print(vt)
    rng = np.random.default_rng(int(ctl.get("seed", 0)))
    setpoints = ctl.get("setpoints_deg") or list(rng.uniform(0, 60, int(ctl.get("random_setpoints", 5))))
    results, _ = simulate_p_control(np.asarray(setpoints, float), geom, kp_V_per_deg=float(ctl.get("kp", 5.0)),
                                    v_min=float(ctl.get("v_min", 2.4)), v_max=float(ctl.get("v_max", 12.0)),
                                    speed_rev_per_s_per_V=float(ctl.get("motor_rev_per_s_per_V", 1.90 / 3.6)),
                                    deadband_deg=float(ctl.get("deadband_deg", 0.5)),
                                    step_s=float(ctl.get("step_s", 20.0)), rate_hz=rate)
    ct = Table(title=f"P control (Kp = {ctl.get('kp', 5.0)}, {ctl.get('v_min', 2.4)} V < Vm < {ctl.get('v_max', 12.0)} V)")
    for c in ("set-point deg", "from deg", "rise time s (10-90 %)", "steady-state error deg"):
        ct.add_column(c, justify="right")
    for r in results:
        ct.add_row(f"{r.setpoint_deg:.2f}", f"{r.start_deg:.2f}", f"{r.rise_time_s:.2f}",
                   f"{r.steady_state_error_deg:.3f}")
    console.print(ct)
    errs = [r.steady_state_error_deg for r in results]
    click.echo(f"steady-state error: mean {np.mean(errs):.3f} deg, max {np.max(errs):.3f} deg")
