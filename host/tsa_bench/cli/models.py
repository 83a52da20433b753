"""Model commands: `tsa-bench fit | predict | manipulator`: the thesis's models on run files (docs/models.md).

Exit codes: 0 success; 2 bad input (missing or unreadable file, unknown model, run
lacking a needed column, bad YAML), with one ``error: <file>: <what>`` line.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import click

from tsa_bench.cli.exits import EXIT_BAD_INPUT, EXIT_FAILED, check_output, unwritable_reason
from tsa_bench.cli.loading import FORCE, MAX_MEMORY

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table

# The names of tsa_bench.models.saved.MODEL_NAMES, here so that --help does not import the models.
MODEL_NAMES = ("preisach", "polynomial", "strain-resistance", "self-sensing", "twist-heat-additive",
               "twist-heat-coupled")


def _fail(msg: str, code: int = EXIT_BAD_INPUT) -> NoReturn:
    click.echo(f"error: {msg}", err=True)
    sys.exit(code)


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
    """A rich console that never wraps or cuts a line when not on a terminal (pipes, logs, tests)."""
    from tsa_bench.console.output import make_console

    return make_console()


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
@MAX_MEMORY
@FORCE
def fit_cmd(model: str, runs: tuple[str, ...], input_col: str | None, output_col: str | None,
            validate: tuple[str, ...], levels: int, load_g: float | None, out: str, force: bool) -> None:
    """Identify MODEL on RUNS; print identification/validation metrics; save the model JSON."""
    from tsa_bench.models.fit_samples import FitError
    from tsa_bench.models.fitting import fit, fit_notes
    from tsa_bench.models.saved import ModelFileError, save_model
    from tsa_bench.outputs import OutputExists

    if not 1 <= levels <= 200:
        _fail(f"--levels must be 1..200 (the thesis uses 20), got {levels}")
    if load_g is not None and not 0 <= load_g < float("inf"):
        _fail(f"--load-g must be a mass >= 0 g, got {load_g}")
    why = unwritable_reason(out)
    if why:   # before the fit, which can take a while on a long run
        _fail(f"{out}: cannot write the model file there ({why})")
    check_output(out, force)
    train = _read(runs)
    val = _read(validate)
    try:
        saved = fit(model, train, input_col, output_col, val, levels=levels, load_g=load_g)
    except (FitError, ModelFileError) as exc:
        _fail(str(exc))
    for note in fit_notes(saved, train):
        click.echo(f"note: {note}", err=True)
    try:
        save_model(saved, out)
    except OutputExists as exc:
        _fail(str(exc))
    except OSError as exc:
        _fail(f"{out}: cannot write the model file ({exc.strerror or exc})")
    rows = [("identification", p, m) for p, m in saved.metrics["identification"].items()]
    rows += [("validation", p, m) for p, m in saved.metrics["validation"].items()]
    _console().print(_metrics_table(f"{model}: {saved.input['column']} -> {saved.output['column']}", rows))
    click.echo(f"model written to {out}")


@click.command("predict")
@click.argument("model_file", type=click.Path(dir_okay=False))
@click.argument("run", type=click.Path(dir_okay=False))
@click.option("--write-prediction", "out", type=click.Path(dir_okay=False), default=None, metavar="OUT.h5",
              help="Write a copy of RUN with the prediction as /samples/predicted_<output> to OUT.h5 "
                   "(RUN itself is never changed; OUT.h5 is never overwritten; saved fit models only).")
@click.option("--holdout", default=None, metavar="SPEC",
              help="Bench file only: the held-out part to score as diagnose chose it (default: diagnose's default "
                   "split; run:N, after:SECONDS or fraction:F as diagnose --holdout).")
@click.option("--json", "json_path", type=click.Path(dir_okay=False), default=None,
              help="Bench file only: also write the figures as JSON (full precision).")
@MAX_MEMORY
@FORCE
def predict_cmd(model_file: str, run: str, out: str | None, holdout: str | None, json_path: str | None,
                force: bool) -> None:
    """Print the metrics of MODEL_FILE (a saved fit model, or a bench file such as the extended model
    `diagnose --write-model` writes) on RUN; optionally write the prediction beside the measurement."""
    if Path(model_file).suffix.lower() in (".yaml", ".yml"):
        if out is not None:
            _fail("--write-prediction is for a saved fit model; a bench file's prediction is scored, not written")
        _predict_bench(model_file, run, holdout, json_path, force)
        return
    if holdout is not None or json_path is not None:
        _fail("--holdout and --json are for a bench file (the extended model diagnose --write-model writes)")
    from tsa_bench.models.fit_samples import FitError
    from tsa_bench.models.fitting import evaluate
    from tsa_bench.models.saved import ModelFileError, load_model_file
    from tsa_bench.store.derived import DerivedFileError, write_with_column

    try:
        saved = load_model_file(model_file)
    except ModelFileError as exc:
        _fail(str(exc))
    check_output(out, force)
    data = _read([run])[0]
    try:
        pred, metrics = evaluate(saved, data)
    except (FitError, ModelFileError) as exc:
        _fail(str(exc) if str(exc).startswith(run) else f"{model_file}: {exc}")
    except (ValueError, TypeError, IndexError, KeyError, ArithmeticError) as exc:  # parameters from a file
        _fail(f"{model_file}: its parameters do not make a {saved.model} model ({type(exc).__name__}: {exc})")
    _console().print(_metrics_table(f"{saved.model} ({Path(model_file).name}): "
                                   f"{saved.input['column']} -> {saved.output['column']}",
                                   [("prediction", run, metrics)]))
    if out is not None:
        name = f"predicted_{saved.output['column']}"
        try:
            write_with_column(run, out, name, pred, saved.output["unit"], {"model_file": str(model_file)})
        except DerivedFileError as exc:
            _fail(str(exc), EXIT_FAILED if "cannot write" in str(exc) else EXIT_BAD_INPUT)
        click.echo(f"prediction written to {out}:/samples/{name} (a copy of {run})")


def _predict_bench(model_file: str, run: str, holdout: str | None, json_path: str | None, force: bool) -> None:
    """A bench file's plant replayed on RUN: RMSE over every sample and over diagnose's held-out part."""
    import json

    from rich.table import Table

    from tsa_bench.analysis import HoldoutError, load_model
    from tsa_bench.analysis.validation import score_model

    try:
        plant = load_model(model_file)
    except Exception as exc:
        msg = str(exc)
        _fail(msg if model_file in msg else f"{model_file}: {msg}")
    if json_path is not None:
        why = unwritable_reason(json_path)
        if why:
            _fail(f"{json_path}: cannot write the figures there ({why})")
    check_output(json_path, force)
    data = _read([run])[0]
    try:
        scores = score_model(plant, [data], holdout)
    except HoldoutError as exc:
        _fail(f"--holdout {holdout!r}: {exc}")
    except ValueError as exc:
        _fail(f"{run}: {exc}")
    units = {"length": "mm", "resistance": "ohm"}
    table = Table(title=f"{Path(model_file).name} (bench plant) on {Path(run).name}: held-out part "
                        f"{holdout or 'as diagnose chooses it by default'}")
    for col in ("output", "RMSE all samples", "RMSE held-out part", "noise RMS", "held-out / noise"):
        table.add_column(col, justify="left" if col == "output" else "right")
    for o, m in scores.items():
        u = units[o]
        table.add_row(o, f"{m['rmse_all']:.6g} {u}", f"{m['rmse_heldout']:.6g} {u}", f"{m['noise_rms']:.4g} {u}",
                      f"{m['rmse_heldout'] / m['noise_rms']:.2f}x")
    _console().print(table)
    if json_path is not None:
        try:
            Path(json_path).write_text(json.dumps({"model": model_file, "run": run, "holdout": holdout,
                                                   "outputs": scores}, indent=2) + "\n")
        except OSError as exc:
            _fail(f"{json_path}: cannot write ({exc.strerror or exc})", EXIT_FAILED)
        click.echo(f"figures written to {json_path}")


#: The manipulator file's sections and keys: (low, high) bounds, "int" for whole numbers.
_MANIPULATOR_KEYS: dict[str, dict[str, tuple]] = {
    "geometry": {"l0_m": (1e-6, 100.0), "r_m": (1e-6, 100.0), "w0_m": (1e-9, 1.0)},
    "twist": {"min_turns": (-1e4, 1e4), "max_turns": (-1e4, 1e4), "points": (2, 10_000, "int")},
    "velocity": {"rate_hz": (1.0, 1e4), "duration_s": (1e-3, 3600.0), "motor_rev_per_s": (-1e3, 1e3),
                 "initial_turns": (-1e4, 1e4)},
    "control": {"kp": (0.0, 1e6), "v_min": (0.0, 1e4), "v_max": (0.0, 1e4), "motor_rev_per_s_per_V": (-1e3, 1e3),
                "deadband_deg": (0.0, 360.0), "random_setpoints": (1, 1000, "int"), "seed": (0, 2**32 - 1, "int"),
                "step_s": (1e-3, 3600.0), "setpoints_deg": None},
}
#: Most samples one simulation of the manipulator may take (rate x duration).
MAX_MANIPULATOR_SAMPLES = 1_000_000


def _manipulator_config(path: str) -> dict[str, Any]:
    """The manipulator YAML, read with the hardened reader and checked key by key."""
    from tsa_bench.userfiles import DocumentError, read_yaml

    try:
        doc = read_yaml(path, what="manipulator file")
        data = doc.data()
    except DocumentError as exc:
        _fail(str(exc))
    if not isinstance(data, dict) or not isinstance(data.get("geometry"), dict):
        _fail(f"{path}: needs a 'geometry' mapping {{l0_m, r_m, w0_m}}")
    out: dict[str, Any] = {}
    for section, value in data.items():
        if section not in _MANIPULATOR_KEYS:
            _fail(f"{doc.where(section)}: unknown section '{section}' (allowed: {', '.join(_MANIPULATOR_KEYS)})")
        if not isinstance(value, dict):
            _fail(f"{doc.where(section)}: {section}: must be a mapping, got {value!r}")
        out[section] = {}
        for key, v in value.items():
            bounds = _MANIPULATOR_KEYS[section].get(key, ...)
            where = f"{doc.where(section, key)}: {section}.{key}"
            if bounds is ...:
                _fail(f"{where}: unknown key (allowed: {', '.join(_MANIPULATOR_KEYS[section])})")
            if bounds is None:  # setpoints_deg: a list of angles
                if not (isinstance(v, list) and 0 < len(v) <= 1000 and all(
                        isinstance(x, (int, float)) and not isinstance(x, bool) and -360 <= x <= 360 for x in v)):
                    _fail(f"{where}: must be a list of 1..1000 angles in -360..360 deg")
                out[section][key] = [float(x) for x in v]
                continue
            whole = len(bounds) == 3
            if isinstance(v, bool) or not isinstance(v, int if whole else (int, float)) \
                    or not bounds[0] <= v <= bounds[1]:
                kind = "a whole number" if whole else "a number"
                _fail(f"{where}: must be {kind} in {bounds[0]:g}..{bounds[1]:g}, got {v!r}")
            out[section][key] = v
    vel = out.get("velocity", {})
    if vel.get("rate_hz", 53.9) * vel.get("duration_s", 7.5) > MAX_MANIPULATOR_SAMPLES:
        _fail(f"{doc.where('velocity')}: velocity: rate_hz x duration_s is more than {MAX_MANIPULATOR_SAMPLES:,} samples")
    if vel.get("rate_hz", 53.9) * vel.get("duration_s", 7.5) < 400:
        _fail(f"{doc.where('velocity')}: velocity: rate_hz x duration_s must give at least 400 samples "
              "(the 151-sample derivative filter)")
    ctl = out.get("control", {})
    steps = len(ctl.get("setpoints_deg") or [0] * ctl.get("random_setpoints", 5))
    if steps * ctl.get("step_s", 20.0) * vel.get("rate_hz", 53.9) > MAX_MANIPULATOR_SAMPLES:
        _fail(f"{doc.where('control')}: control: set-points x step_s x rate_hz is more than "
              f"{MAX_MANIPULATOR_SAMPLES:,} samples")
    return out


def _p_control(simulate, setpoints, geom, ctl: dict[str, Any], rate: float):
    return simulate(setpoints, geom, kp_V_per_deg=float(ctl.get("kp", 5.0)),
                    v_min=float(ctl.get("v_min", 2.4)), v_max=float(ctl.get("v_max", 12.0)),
                    speed_rev_per_s_per_V=float(ctl.get("motor_rev_per_s_per_V", 1.90 / 3.6)),
                    deadband_deg=float(ctl.get("deadband_deg", 0.5)), step_s=float(ctl.get("step_s", 20.0)),
                    rate_hz=rate)


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
        _fail(f"{config}: geometry: {exc}")
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
    try:
        results, _ = _p_control(simulate_p_control, np.asarray(setpoints, float), geom, ctl, rate)
    except ValueError as exc:
        _fail(f"{config}: control: {exc}")
    ct = Table(title=f"P control (Kp = {ctl.get('kp', 5.0)}, {ctl.get('v_min', 2.4)} V < Vm < {ctl.get('v_max', 12.0)} V)")
    for c in ("set-point deg", "from deg", "rise time s (10-90 %)", "steady-state error deg"):
        ct.add_column(c, justify="right")
    for r in results:
        ct.add_row(f"{r.setpoint_deg:.2f}", f"{r.start_deg:.2f}", f"{r.rise_time_s:.2f}",
                   f"{r.steady_state_error_deg:.3f}")
    console.print(ct)
    errs = [r.steady_state_error_deg for r in results]
    click.echo(f"steady-state error: mean {np.mean(errs):.3f} deg, max {np.max(errs):.3f} deg")
