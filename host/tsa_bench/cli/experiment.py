"""Experiment commands: `tsa-bench run | validate | sim-serve | effects`.

Exit codes as in :mod:`tsa_bench.cli`.
"""

from __future__ import annotations

import datetime as dt
import re
import signal
import sys
import urllib.parse
from pathlib import Path

import click

from tsa_bench.bench import BenchConfig, BenchConfigError, load_bench
from tsa_bench.cli.exits import EXIT_ABORTED, EXIT_BAD_INPUT, EXIT_FAILED
from tsa_bench.plan import PlanErrors, format_summary, load_plan


def _load_bench_or_exit(path: str | None) -> BenchConfig:
    try:
        return load_bench(path)
    except BenchConfigError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(EXIT_BAD_INPUT)


def _load_plan_or_exit(path: str, bench: BenchConfig):
    try:
        return load_plan(path, bench.limits)
    except PlanErrors as exc:
        click.echo(f"error: {path} is not a valid protocol; nothing was sent to any device:", err=True)
        click.echo(str(exc), err=True)
        sys.exit(EXIT_BAD_INPUT)


@click.command()
@click.argument("protocol", type=click.Path(dir_okay=False))
@click.option("--bench", "bench_path", type=click.Path(dir_okay=False), default=None,
              help="Bench file (default: configs/bench/sim.yaml, the simulated bench).")
def validate(protocol: str, bench_path: str | None) -> None:
    """Check PROTOCOL against the schema and the bench limits; print the compiled plan."""
    bench = _load_bench_or_exit(bench_path)
    plan = _load_plan_or_exit(protocol, bench)
    click.echo(format_summary(plan))
    click.echo(f"valid for bench '{bench.name}'")


def _sim_url(bench: BenchConfig, speed: float | None, seed: int | None) -> str:
    query = {}
    if bench.path:
        query["bench"] = str(Path(bench.path).resolve())
    if speed:
        query["speed"] = repr(speed)
    if seed is not None:
        query["seed"] = str(seed)
    return "sim://" + ("?" + urllib.parse.urlencode(query) if query else "")


def _out_path(out_dir: str, plan_name: str) -> Path:
    stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    safe = re.sub(r"[^A-Za-z0-9_.-]+", "-", plan_name).strip("-") or "run"
    path = Path(out_dir) / f"{stamp}_{safe}.h5"
    n = 1
    while path.exists():
        n += 1
        path = Path(out_dir) / f"{stamp}_{safe}-{n}.h5"
    return path


def _start_simavr(bench: BenchConfig, speed: float | None, seed: int | None):
    """Build and start the firmware-in-the-loop bench; exit with a clear error if it cannot."""
    import dataclasses

    from tsa_bench.simavr import SimavrBench, SimavrError, simavr_settings
    try:
        settings = simavr_settings(bench)
        if speed:
            settings = dataclasses.replace(settings, realtime_factor=speed)
        return SimavrBench(bench, settings, seed=seed).__enter__()
    except BenchConfigError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(EXIT_BAD_INPUT)
    except SimavrError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(EXIT_FAILED)


def _report_simavr(fil) -> None:
    """One line from the harness summary; violations and crashes loudly."""
    s = fil.summary
    if not s:
        click.echo(f"warning: the simavr harness left no summary (exit code {fil.returncode}): {fil.stderr_text}",
                   err=True)
        return
    bad = {k: v for k, v in s["violations"].items() if v}
    click.echo(f"simavr       {s['device_time_s']:.1f} s of device time, {s['steps']['total']} steps, "
               f"violations: {bad or 'none'}" + (" - FIRMWARE CRASHED" if s["crashed"] else ""))


def _raise_interrupt(signum, frame):  # SIGTERM ends a run like Ctrl-C: STOP, file closed "aborted"
    raise KeyboardInterrupt


@click.command()
@click.argument("protocol", type=click.Path(dir_okay=False))
@click.option("--bench", "bench_path", type=click.Path(dir_okay=False), default=None,
              help="Bench file (default: configs/bench/sim.yaml, the simulated bench).")
@click.option("--port", default=None, help="Serial device or pyserial URL; overrides the bench file's backend.")
@click.option("--out", "out_dir", default="runs", show_default=True, help="Directory for the run file.")
@click.option("--output", "out_file", type=click.Path(dir_okay=False), default=None,
              help="Exact run-file path (overrides --out).")
@click.option("--speed", type=float, default=None,
              help="Simulated benches only: real-time factor (1 = wall-clock pace); default as fast as possible.")
@click.option("--seed", type=int, default=None, help="Simulated bench only: noise seed.")
def run(protocol: str, bench_path: str | None, port: str | None, out_dir: str, out_file: str | None,
        speed: float | None, seed: int | None) -> None:
    """Run PROTOCOL on the bench and write one HDF5 run file."""
    import serial

    from tsa_bench import transport  # noqa: F401  (registers the sim:// URL handler)
    from tsa_bench.console.progress import ProgressDisplay
    from tsa_bench.console.summary import format_run_info
    from tsa_bench.device import BenchClient, DeviceError
    from tsa_bench.runner import AutoOperator, ConsoleOperator, PlanRejected, Runner, check_plan_against_device
    from tsa_bench.store import RunWriter
    from tsa_bench.store.inspect import inspect_run
    from tsa_bench.store.live import LiveSidecar

    bench = _load_bench_or_exit(bench_path)
    plan = _load_plan_or_exit(protocol, bench)
    if speed is not None and speed <= 0:
        click.echo("error: --speed must be > 0 (a real-time factor)", err=True)
        sys.exit(EXIT_BAD_INPUT)
    fil = None  # firmware in the loop (simavr)
    if port is None and bench.backend == "sim":
        url, backend = _sim_url(bench, speed, seed), "sim"
        click.echo(f"tsa-bench: running '{plan.name}' on the SIMULATED bench ({bench.name}); no hardware is used")
    elif port is None and bench.backend == "simavr":
        fil = _start_simavr(bench, speed, seed)
        url, backend = fil.port_path, "simavr"
        click.echo(f"tsa-bench: running '{plan.name}' on the firmware in simavr ({bench.name}); no hardware is used")
    else:
        url = port or bench.port
        if not url:
            click.echo(f"error: {bench.path}: backend is serial but no port is given (use --port)", err=True)
            sys.exit(EXIT_BAD_INPUT)
        backend = "sim" if url.startswith("sim://") else "serial"
        click.echo(f"tsa-bench: running '{plan.name}' on {url} at {bench.baud} baud ({bench.name})")
    try:
        ser = serial.serial_for_url(url, baudrate=bench.baud, timeout=0.05, write_timeout=2.0)
    except (serial.SerialException, ValueError, OSError) as exc:
        if fil is not None:
            fil.close()
        click.echo(f"error: cannot open {url}: {exc}\n  check the device is plugged in, the port name "
                   "(`python -m serial.tools.list_ports`), and that no other program holds it", err=True)
        sys.exit(EXIT_FAILED)
    old_term = signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        if fil is not None:
            fil.start()  # release the emulated AVR from reset, as the DTR line does on a Mega
        client = BenchClient(ser, ack_timeout_s=bench.ack_timeout_s)
        try:
            ident = client.connect(bench.boot_timeout_s, baud=bench.baud)
            check_plan_against_device(plan, ident)
        except (DeviceError, PlanRejected) as exc:
            click.echo(f"error: {exc}; nothing was run", err=True)
            sys.exit(EXIT_BAD_INPUT if isinstance(exc, PlanRejected) else EXIT_FAILED)
        except KeyboardInterrupt:
            click.echo("aborted before the run started; nothing was run", err=True)
            sys.exit(EXIT_ABORTED)
        path = Path(out_file) if out_file else _out_path(out_dir, plan.name)
        if path.exists():  # never overwrite recorded data
            click.echo(f"error: {path} already exists; choose another --output; nothing was run", err=True)
            sys.exit(EXIT_BAD_INPUT)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with open(path, "ab"):
                pass
            path.unlink()
        except OSError as exc:
            click.echo(f"error: cannot write the run file {path}: {exc}; nothing was run", err=True)
            sys.exit(EXIT_BAD_INPUT)
        writer = RunWriter(path)
        operator = AutoOperator() if ident.flags & 1 else ConsoleOperator()
        if fil is not None:
            from tsa_bench.simavr.operator import PlantOperator
            operator = PlantOperator(fil)
            operator.apply_initial(plan.load_g)
        consumers = [writer, LiveSidecar(path), ProgressDisplay()]  # sidecar after the writer: tsa-bench watch
        runner = Runner(client, plan, bench, consumers, operator, backend=backend, port_name=url)
        stop = runner.run()
    finally:
        signal.signal(signal.SIGTERM, old_term)
        ser.close()
        if fil is not None:
            fil.close()
            _report_simavr(fil)
    click.echo(format_run_info(inspect_run(path)))
    rtf = stop.t_end / stop.wall_time_s if stop.wall_time_s > 0 else float("inf")
    click.echo(f"wall time    {stop.wall_time_s:.2f} s (real-time factor {rtf:.0f})")
    click.echo(f"wrote {path}")
    sys.exit({"success": 0, "aborted": EXIT_ABORTED}.get(stop.exit_status, EXIT_FAILED))


@click.command()
@click.option("--bench", "bench_path", type=click.Path(dir_okay=False), default=None,
              help="Also show which effects this simulated bench switches on and its values.")
def effects(bench_path: str | None) -> None:
    """List the simulated plant's physical effects with their parameters, units and defaults."""
    from tsa_bench.sim.effects import describe_effects

    configured: dict = {}
    if bench_path is not None:
        bench = _load_bench_or_exit(bench_path)
        configured = bench.plant.get("effects", {}) or {}
    for effect in describe_effects():
        name = effect["name"]
        cfg = configured.get(name, {}) if isinstance(configured, dict) else {}
        cfg = {"enabled": cfg} if isinstance(cfg, bool) else cfg or {}
        state = ""
        if bench_path is not None:
            on = cfg.get("enabled", effect["default_enabled"])
            state = "  [on]" if on else "  [off]"
        elif not effect["default_enabled"]:
            state = "  [off unless a bench file switches it on]"
        click.echo(f"{name}  ({effect['stage']}){state}")
        click.echo(f"    {effect['doc']}")
        click.echo(f"    source: {effect['source']}")
        for p in effect["params"]:
            value = cfg.get(p["name"], p["default"])
            shown = f"{value!r}" + ("" if value == p["default"] else f" (default {p['default']!r})")
            click.echo(f"    {p['name']:<28} {shown:<24} {p['units']:<10} {p['doc']}")
        click.echo("")


@click.command("sim-serve")
@click.option("--bench", "bench_path", type=click.Path(dir_okay=False), default=None,
              help="Bench file (default: configs/bench/sim.yaml).")
@click.option("--speed", type=float, default=None, help="Real-time factor; default as fast as the client reads.")
@click.option("--seed", type=int, default=None, help="Noise seed.")
def sim_serve(bench_path: str | None, speed: float | None, seed: int | None) -> None:
    """Serve the simulated bench on a pseudo-terminal; prints its path, runs until Ctrl-C."""
    from tsa_bench.transport.pty_server import serve_pty

    bench = _load_bench_or_exit(bench_path)

    def ready(path: str) -> None:
        click.echo(path)
        click.echo(f"simulated bench '{bench.name}' serving on {path}; "
                   f"run: tsa-bench run PROTOCOL --port {path}   (Ctrl-C stops)", err=True)
        sys.stdout.flush()

    try:
        serve_pty(bench, speed, seed, ready)
    except KeyboardInterrupt:
        pass

