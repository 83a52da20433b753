"""`tsa-bench calibrate position | resistance`: reference readings -> a new bench file.

Exit codes as in :mod:`tsa_bench.cli`.
"""

from __future__ import annotations

import datetime as dt
import sys
from pathlib import Path

import click

from tsa_bench.cli.exits import EXIT_ABORTED, EXIT_BAD_INPUT, EXIT_FAILED, fail
from tsa_bench.cli.loading import ALLOW_URL


@click.group()
def calibrate() -> None:
    """Turn ruler readings (position) or reference resistors (resistance) into a calibration,
    written with a dated record into a new bench file."""


def _numbers(text: str | None, option: str) -> list[float]:
    if not text:
        return []
    try:
        return [float(x) for x in text.replace(";", ",").split(",") if x.strip()]
    except ValueError:
        fail(f"{option}: {text!r} is not a comma-separated list of numbers")


def _pairs(text: str, unit: str) -> tuple[list[float], list[float]]:
    counts, refs = [], []
    for part in text.split(","):
        if not part.strip():
            continue
        c, sep, r = part.partition("=")
        try:
            counts.append(float(c))
            refs.append(float(r.strip().removesuffix(unit)))
        except ValueError:
            fail(f"--points: {part.strip()!r} is not COUNTS={unit.upper()}, e.g. 11200=240.5")
        if not sep:
            fail(f"--points: {part.strip()!r} is not COUNTS={unit.upper()}, e.g. 11200=240.5")
    return counts, refs


def _ask(prompt: str) -> str:
    """A typed reading through the operator channel ("" = Enter alone, also at the end of the input)."""
    from tsa_bench.operator import OperatorAbsent
    from tsa_bench.operator.terminal import TerminalOperator

    try:
        return TerminalOperator().ask(prompt)
    except OperatorAbsent:
        return ""


def _target(bench, quantity: str, out: str | None) -> Path:
    """The new bench file: --out, or BENCH-<quantity>-<date>.yaml here."""
    source = Path(bench.path or "bench.yaml")
    return Path(out) if out else Path(f"{source.stem}-{quantity}-{dt.date.today():%Y%m%d}.yaml")


def _keep_points(quantity: str, bench, kept: list[tuple[float, float]], out: str | None, why: str) -> None:
    """After a failure mid-acquisition: the points measured so far, saved beside the bench file
    that would have been written and printed as a command that re-fits them without the rig."""
    from tsa_bench.rig.calibration import points_text

    if not kept:
        click.echo(f"{why}; no point was complete, nothing was written", err=True)
        return
    command = (f"tsa-bench calibrate {quantity} --bench {bench.path} --points {points_text(kept)}"
               + (f" --out {out}" if out else ""))
    target = _target(bench, quantity, out)   # beside the bench file it would have written
    from tsa_bench.outputs import OutputExists, write_text

    n = 1
    while True:   # the next free name, created exclusively (never through a link, never replacing a file)
        saved = target.with_name(f"{target.stem}-points.txt" if n == 1 else f"{target.stem}-points-{n}.txt")
        try:
            write_text(saved, f"# {len(kept)} point(s) measured before: {why}\n{command}\n", force=False)
            where = f"saved in {saved}"
            break
        except OutputExists:
            n += 1
        except OSError as exc:
            where = f"not saved ({exc.strerror or exc})"
            break
    click.echo(f"{why}; the {len(kept)} point(s) measured so far are kept ({where}). Re-fit them without "
               f"the rig (add points by hand as COUNTS=VALUE):\n  {command}", err=True)


def _calibrate(quantity: str, port, bench_path, at_turns, points, seconds, out, note, allow_url) -> None:
    from tsa_bench.cli.rig import _open_or_exit, _rig
    from tsa_bench.cli.loading import load_bench_or_exit
    from tsa_bench.rig.benchfile import BenchWriteError, write_new_bench
    from tsa_bench.rig.calibration import CalibrationError, acquire, device_text, fit_for
    from tsa_bench.device import DeviceError
    from tsa_bench.rig.link import RigError

    unit = "mm" if quantity == "position" else "ohm"
    turns = _numbers(at_turns, "--at-turns")
    device = ""
    error = 0.0
    if points:
        if port or turns:
            fail("--points fits points already measured: give it without --port and --at-turns")
        bench = load_bench_or_exit(bench_path, None, allow_url=allow_url, trust_firmware_dir=True)
        counts, refs = _pairs(points, unit)
    else:
        bench, url = _rig(port, bench_path, allow_url)
        lim = bench.limits
        for t in turns:
            if (lim.max_twist_turns is not None and t > lim.max_twist_turns) or \
                    (lim.min_twist_turns is not None and t < lim.min_twist_turns):
                fail(f"--at-turns: {t:g} turns is outside the bench's twist limits")
        kept: list[tuple[float, float]] = []
        try:
            with _open_or_exit(url, bench) as link:
                device = device_text(link)
                if turns:
                    zeroed = link.require_position()
                    if zeroed:
                        click.echo(zeroed)
                try:
                    counts, refs, error = acquire(link, quantity, _ask, at_turns=turns, seconds=seconds,
                                                  say=click.echo, kept=kept)
                except (RigError, DeviceError) as exc:
                    _keep_points(quantity, bench, kept, out, f"error: {exc}")
                    sys.exit(EXIT_FAILED)
        except CalibrationError as exc:
            _keep_points(quantity, bench, kept, out, f"error: {exc}")
            sys.exit(EXIT_BAD_INPUT)
        except KeyboardInterrupt:
            _keep_points(quantity, bench, kept, out, "aborted (Ctrl-C); no bench file was written")
            sys.exit(EXIT_ABORTED)
    try:
        fit = fit_for(quantity, counts, refs, bench, error)
    except CalibrationError as exc:
        fail(str(exc))
    click.echo(f"{'counts':>12} {'reference':>12} {'fit':>12} {'residual':>10}   ({unit})")
    for c, r, f, e in zip(fit.counts, fit.reference, fit.fitted, fit.residuals):
        click.echo(f"{c:12.2f} {r:12.5g} {f:12.5g} {e:+10.3g}")
    click.echo(f"rms residual {fit.rms_residual:.3g} {unit}")
    click.echo(", ".join(f"{k} = {v:.8g}" for k, v in fit.result.items()))
    source = Path(bench.path or "bench.yaml")
    target = _target(bench, quantity, out)
    try:
        written = write_new_bench(bench.source_text, str(source), target, quantity, fit.result,
                                  fit.record(device, note or ""))
    except BenchWriteError as exc:
        fail(str(exc))
    except OSError as exc:
        fail(f"cannot write {target}: {exc.strerror or exc}", EXIT_FAILED)
    click.echo(f"wrote {written} (use it with --bench)")


def _options(unit: str, what: str):
    def wrap(f):
        for opt in reversed([
            click.option("--port", default=None, help="Serial device (or sim://); default: the bench file's port."),
            click.option("--bench", "bench_path", type=click.Path(dir_okay=False), default=None,
                         help="The bench file to calibrate (default: configs/bench/arduino-mega.yaml with a "
                              "serial port)."),
            click.option("--at-turns", default=None, metavar="T1,T2,...",
                         help="Move to each twist before reading a point (back to the start at the end)."),
            click.option("--points", default=None, metavar=f"COUNTS={unit.upper()},...",
                         help=f"Fit these points (raw counts = {what}) without a device."),
            click.option("--seconds", type=click.FloatRange(0.05, 600), default=1.0, show_default=True,
                         help="Readings averaged per point (s of device time)."),
            click.option("--out", default=None, type=click.Path(dir_okay=False),
                         help="New bench file (default: BENCH-<quantity>-<date>.yaml here; never overwritten)."),
            click.option("--note", default=None, help="A note kept in the calibration record."),
            ALLOW_URL,
        ]):
            f = opt(f)
        return f
    return wrap


@calibrate.command("position")
@_options("mm", "ruler length in mm")
def position(port, bench_path, at_turns, points, seconds, out, note, allow_url) -> None:
    """Ruler readings at two or more lengths -> position_sensor mm_per_count and offset_mm."""
    _calibrate("position", port, bench_path, at_turns, points, seconds, out, note, allow_url)


@calibrate.command("resistance")
@_options("ohm", "reference resistance in ohm")
def resistance(port, bench_path, at_turns, points, seconds, out, note, allow_url) -> None:
    """Reference resistors (or an ohmmeter) at two or more values -> resistance_sensor gain and offset_ohm."""
    _calibrate("resistance", port, bench_path, at_turns, points, seconds, out, note, allow_url)
