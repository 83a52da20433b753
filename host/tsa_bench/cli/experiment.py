"""Experiment commands: `tsa-bench run | validate | sim-serve | effects`.

Exit codes as in :mod:`tsa_bench.cli`.
"""

from __future__ import annotations

import datetime as dt
import os
import re
import signal
import sys
import urllib.parse
from pathlib import Path

import click

from tsa_bench.bench import BenchConfig, BenchConfigError, load_bench
from tsa_bench.cli.exits import EXIT_ABORTED, EXIT_BAD_INPUT, EXIT_FAILED, fail
from tsa_bench.plan import PlanErrors, format_summary, load_plan


def _load_bench_or_exit(path: str | None, *, allow_url: bool = False, trust_firmware_dir: bool = False) -> BenchConfig:
    try:
        return load_bench(path, allow_url=allow_url, trust_firmware_dir=trust_firmware_dir)
    except BenchConfigError as exc:
        fail(str(exc))


def _load_plan_or_exit(path: str, bench: BenchConfig):
    """The protocol, compiled under the bench limits, with every device command checked to
    fit the wire: `validate` and `run` refuse exactly the same protocols."""
    from tsa_bench.runner.commands import plan_problems

    try:
        plan = load_plan(path, bench.limits)
    except PlanErrors as exc:
        fail(f"{path} is not a valid protocol; nothing was sent to any device:\n{exc}")
    problems = plan_problems(plan, bench.steps_per_turn)
    if problems:
        fail(f"{path} cannot be sent to bench '{bench.name}'; nothing was sent to any device:\n"
             + "\n".join(problems))
    return plan


def _check_port_or_exit(port: str | None, allow_url: bool) -> None:
    from tsa_bench.bench.ports import PortPolicyError, check_port

    if port is not None:
        try:
            check_port(port, allow_url=allow_url)
        except PortPolicyError as exc:
            fail(f"--port: {exc}")


_ALLOW_URL = click.option("--allow-url", is_flag=True,
                          help="Allow any pyserial URL as the port (spy://, socket://, ...); by default only serial "
                               "device paths and sim:// are allowed.")
_TRUST_FW = click.option("--trust-firmware-dir", is_flag=True,
                         help="Let a simavr bench build firmware in a folder other than this project's firmware/.")


@click.command()
@click.argument("protocol", type=click.Path(dir_okay=False))
@click.option("--bench", "bench_path", type=click.Path(dir_okay=False), default=None,
              help="Bench file (default: configs/bench/sim.yaml, the simulated bench).")
@click.option("--port", default=None, help="Serial device the run would use (checked like `run --port`).")
@_ALLOW_URL
@_TRUST_FW
def validate(protocol: str, bench_path: str | None, port: str | None, allow_url: bool,
             trust_firmware_dir: bool) -> None:
    """Check PROTOCOL and the bench file as `run` would (schema, limits, device commands, plant);
    print the compiled plan."""
    _check_port_or_exit(port, allow_url)
    bench = _load_bench_or_exit(bench_path, allow_url=allow_url, trust_firmware_dir=trust_firmware_dir)
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


def _start_simavr(bench: BenchConfig, speed: float | None, seed: int | None, trust_firmware_dir: bool):
    """Build and start the firmware-in-the-loop bench; exit with a clear error if it cannot."""
    import dataclasses

    from tsa_bench.simavr import SimavrBench, SimavrError, simavr_settings
    try:
        settings = simavr_settings(bench, trust_firmware_dir=trust_firmware_dir)
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


@click.command()
@click.argument("protocol", type=click.Path(dir_okay=False))
@click.option("--bench", "bench_path", type=click.Path(dir_okay=False), default=None,
              help="Bench file (default: configs/bench/sim.yaml, the simulated bench).")
@click.option("--port", default=None, help="Serial device (or sim://); overrides the bench file's backend.")
@click.option("--out", "out_dir", default="runs", show_default=True, help="Directory for the run file.")
@click.option("--output", "out_file", type=click.Path(dir_okay=False), default=None,
              help="Exact run-file path (overrides --out).")
@click.option("--speed", type=float, default=None,
              help="Simulated benches only: real-time factor (1 = wall-clock pace); default as fast as possible.")
@click.option("--seed", type=int, default=None, help="Simulated bench only: noise seed.")
@_ALLOW_URL
@_TRUST_FW
def run(protocol: str, bench_path: str | None, port: str | None, out_dir: str, out_file: str | None,
        speed: float | None, seed: int | None, allow_url: bool, trust_firmware_dir: bool) -> None:
    """Run PROTOCOL on the bench and write one HDF5 run file.

    Ctrl-C or SIGTERM sends STOP at once and closes the file "aborted" (exit 130); a
    second one only hurries the end. A full disk ends the run "failed" (exit 1).
    """
    from tsa_bench.runner.interrupts import Interrupts

    # SIGINT/SIGTERM: immediate until the run starts, then deferred to safe points.
    # A file-size limit (ulimit -f) makes writes fail instead of killing the process.
    interrupts = Interrupts()
    interrupts.install()
    if hasattr(signal, "SIGXFSZ"):
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    try:
        with interrupts.immediate():
            session = _prepare_run(protocol, bench_path, port, out_dir, out_file, speed, seed, allow_url,
                                   trust_firmware_dir)
        code = _execute_run(session, interrupts)
    except KeyboardInterrupt:
        click.echo("aborted before the run started; nothing was run", err=True)
        code = EXIT_ABORTED
    finally:
        if interrupts.requested:
            # Exiting 130: a further signal must not change that, nor kill the process
            # while Python shuts down (it puts default handlers back, but keeps SIG_IGN).
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, signal.SIG_IGN)
        else:
            interrupts.restore()
    sys.exit(code)


def _prepare_run(protocol, bench_path, port, out_dir, out_file, speed, seed, allow_url, trust_firmware_dir):
    """Everything that can be refused before anything is opened: bench, protocol, port,
    output path, free space. Exits 2 (bad input) or 1 (no room) with nothing sent."""
    from tsa_bench.store.space import StorageFull, ensure_room, run_bytes

    _check_port_or_exit(port, allow_url)
    bench = _load_bench_or_exit(bench_path, allow_url=allow_url, trust_firmware_dir=trust_firmware_dir)
    plan = _load_plan_or_exit(protocol, bench)
    if speed is not None and not (speed > 0 and speed < float("inf")):
        fail("--speed must be > 0 (a real-time factor)")
    path = Path(out_file) if out_file else _out_path(out_dir, plan.name)
    if path.exists() or path.is_symlink():  # never overwrite recorded data
        fail(f"{path} already exists; choose another --output; nothing was run")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        fail(f"cannot write the run file {path}: {exc.strerror or exc}; nothing was run")
    if not path.parent.is_dir() or not os.access(path.parent, os.W_OK):
        fail(f"cannot write the run file {path}: its folder is not writable; nothing was run")
    summary = plan.summary()
    period_s = min(plan.sampling_period_s, summary.sampling_period_range_s[0] or plan.sampling_period_s)
    try:
        ensure_room(path, run_bytes(summary.duration_s / period_s, len(plan.segments)), "this run")
    except StorageFull as exc:
        fail(f"{exc}; free some space or choose another --out; nothing was run", EXIT_FAILED)
    return dict(bench=bench, plan=plan, port=port, path=path, speed=speed, seed=seed,
                trust_firmware_dir=trust_firmware_dir)


def _execute_run(session: dict, interrupts) -> int:
    """Open the bench, run, summarise; return the exit code."""
    import serial

    from tsa_bench import transport  # noqa: F401  (registers the sim:// URL handler)
    from tsa_bench.console.progress import ProgressDisplay
    from tsa_bench.console.summary import format_run_info
    from tsa_bench.device import BenchClient, DeviceError
    from tsa_bench.runner import AutoOperator, ConsoleOperator, PlanRejected, Runner, check_plan_against_device
    from tsa_bench.store import RunFileError, RunWriter
    from tsa_bench.store.inspect import inspect_run
    from tsa_bench.store.live import LiveSidecar

    bench, plan, port, path = session["bench"], session["plan"], session["port"], session["path"]
    speed, seed = session["speed"], session["seed"]
    fil = None  # firmware in the loop (simavr)
    with interrupts.immediate():
        if port is None and bench.backend == "sim":
            url, backend = _sim_url(bench, speed, seed), "sim"
            click.echo(f"tsa-bench: running '{plan.name}' on the SIMULATED bench ({bench.name}); no hardware is used")
        elif port is None and bench.backend == "simavr":
            fil = _start_simavr(bench, speed, seed, session["trust_firmware_dir"])
            url, backend = fil.port_path, "simavr"
            click.echo(f"tsa-bench: running '{plan.name}' on the firmware in simavr ({bench.name}); "
                       "no hardware is used")
        else:
            url = port or bench.port
            if not url:
                fail(f"{bench.path}: backend is serial but no port is given (use --port)")
            backend = "sim" if url.startswith("sim://") else "serial"
            click.echo(f"tsa-bench: running '{plan.name}' on {url} at {bench.baud} baud ({bench.name})")
        try:
            ser = serial.serial_for_url(url, baudrate=bench.baud, timeout=0.05, write_timeout=2.0)
        except (serial.SerialException, ValueError, OSError) as exc:
            if fil is not None:
                fil.close()
            fail(f"cannot open {url}: {exc}\n  check the device is plugged in, the port name "
                 "(`python -m serial.tools.list_ports`), and that no other program holds it", EXIT_FAILED)
    writer = None
    try:
        with interrupts.immediate():
            if fil is not None:
                fil.start()  # release the emulated AVR from reset, as the DTR line does on a Mega
            client = BenchClient(ser, ack_timeout_s=bench.ack_timeout_s, watchdog_s=bench.watchdog_s)
            try:
                ident = client.connect(bench.boot_timeout_s, baud=bench.baud)
                check_plan_against_device(plan, ident)
            except (DeviceError, PlanRejected) as exc:
                fail(f"{exc}; nothing was run", EXIT_BAD_INPUT if isinstance(exc, PlanRejected) else EXIT_FAILED)
            writer = RunWriter(path)
            operator = AutoOperator() if ident.flags & 1 else ConsoleOperator()
            if fil is not None:
                from tsa_bench.simavr.operator import PlantOperator
                operator = PlantOperator(fil)
                operator.apply_initial(plan.load_g)
        consumers = [writer, LiveSidecar(path), ProgressDisplay()]  # sidecar after the writer: tsa-bench watch
        runner = Runner(client, plan, bench, consumers, operator, backend=backend, port_name=url,
                        interrupts=interrupts)
        stop = runner.run()
    finally:
        ser.close()
        if fil is not None:
            fil.close()
            _report_simavr(fil)
    if writer is not None and writer.broken:
        # The HDF5 library failed a write: its state is broken and it would crash on exit.
        click.echo(f"error: run failed: {writer.broken}; the samples are in {path}.live "
                   "(tsa-bench watch reads it)", err=True)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(EXIT_FAILED)
    if path.exists():
        try:
            click.echo(format_run_info(inspect_run(path)))
        except RunFileError as exc:
            click.echo(f"error: {exc}", err=True)
    rtf = stop.t_end / stop.wall_time_s if stop.wall_time_s > 0 else float("inf")
    click.echo(f"wall time    {stop.wall_time_s:.2f} s (real-time factor {rtf:.0f})")
    if stop.exit_status != "success" or (writer is not None and writer.full):
        reason = writer.full if writer is not None and writer.full and stop.exit_status == "success" else stop.reason
        status = "failed" if stop.exit_status == "success" else stop.exit_status
        click.echo(f"run {status}: {reason}", err=True)
    click.echo(f"wrote {path}" if path.exists() else f"no run file was written ({path})")
    if writer is not None and writer.full and stop.exit_status == "success":
        return EXIT_FAILED
    return {"success": 0, "aborted": EXIT_ABORTED}.get(stop.exit_status, EXIT_FAILED)


@click.command()
@click.option("--bench", "bench_path", type=click.Path(dir_okay=False), default=None,
              help="Also show which effects this simulated bench switches on and its values.")
def effects(bench_path: str | None) -> None:
    """List the simulated plant's physical effects with their parameters, units and defaults."""
    from tsa_bench.sim.effects import describe_effects

    configured: dict = {}
    if bench_path is not None:
        bench = _load_bench_or_exit(bench_path, allow_url=True, trust_firmware_dir=True)  # only shown
        configured = bench.plant.get("effects", {}) or {}
    for effect in describe_effects():
        name = effect["name"]
        cfg = configured.get(name) if isinstance(configured, dict) else None
        cfg = {"enabled": cfg} if isinstance(cfg, bool) else cfg if isinstance(cfg, dict) else {}
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

