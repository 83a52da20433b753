"""`tsa-bench run`: one protocol on one bench, one HDF5 run file (or `--resume` one).

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

from tsa_bench.cli.exits import EXIT_ABORTED, EXIT_BAD_INPUT, EXIT_FAILED, fail
from tsa_bench.cli.catalogue import CATALOGUE_OPTION
from tsa_bench.cli.loading import (
    ALLOW_URL, MAX_MEMORY, SET_OPTION, TRUST_FW, check_port_or_exit, is_serial_port, load_bench_or_exit,
    load_plan_or_exit, meta_pairs, variable_values,
)


def _sim_url(bench_file: str | None, speed: float | None, seed: int | None) -> str:
    query = {}
    if bench_file:
        query["bench"] = str(Path(bench_file).resolve())
    if speed:
        query["speed"] = repr(speed)
    if seed is not None:
        query["seed"] = str(seed)
    return "sim://" + ("?" + urllib.parse.urlencode(query) if query else "")


#: Longest plan-name part of a run file's name (characters): a name may be 255 bytes.
MAX_NAME_CHARS = 80


def _safe_name(plan_name: str) -> str:
    safe = re.sub(r"[^A-Za-z0-9_.-]+", "-", plan_name).strip("-.") or "run"
    return safe[:MAX_NAME_CHARS].rstrip("-.") or "run"


def _out_path(out_dir: str, plan_name: str) -> Path:
    """Reserve (create empty, exclusively) the next free ``DATE-TIME_PLAN[-n].h5`` in ``out_dir``:
    runs started together into one folder get different names."""
    from tsa_bench.outputs import reserve_free_name

    stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    return reserve_free_name(out_dir, f"{stamp}_{_safe_name(plan_name)}")


def _resumed_path(first: Path) -> Path:
    from tsa_bench.outputs import reserve_free_name

    return reserve_free_name(first.parent, f"{first.stem[:MAX_NAME_CHARS + 20]}-resumed")


def reserve_run_file(out_dir: str, plan_name: str, out_file: str | None, resume_file: str | None = None) -> Path:
    """The run file, reserved for this process (created empty, O_EXCL, never through a link):
    ``out_file`` exactly, else the next free name in ``out_dir`` (or beside a resumed run).
    Exits 2 when it cannot be; :func:`release_run_file` gives it back if nothing is recorded."""
    from tsa_bench.outputs import create_new

    path = Path(out_file) if out_file else None
    try:
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            os.close(create_new(path))
            return path
        if resume_file is not None and out_dir == "runs":
            return _resumed_path(Path(resume_file))
        Path(out_dir).mkdir(parents=True, exist_ok=True)
        return _out_path(out_dir, plan_name)
    except FileExistsError:
        fail(f"{path} already exists; choose another --output (recorded data is never overwritten); nothing was run")
    except OSError as exc:
        fail(f"cannot write the run file in {out_file or out_dir}: {exc.strerror or exc}; nothing was run")
    raise AssertionError("unreachable")


def release_run_file(path: Path) -> None:
    """Remove a reserved run file that nothing was written to (the run never started)."""
    from tsa_bench.store.live import sidecar_path

    try:
        if path.is_file() and not path.is_symlink() and path.stat().st_size == 0 \
                and not os.path.lexists(sidecar_path(path)):
            path.unlink()
    except OSError:
        pass


def _start_simavr(bench, speed: float | None, seed: int | None, trust_firmware_dir: bool):
    """Build and start the firmware-in-the-loop bench; exit with a clear error if it cannot."""
    import dataclasses

    from tsa_bench.bench import BenchConfigError
    from tsa_bench.bench.simavr_section import simavr_settings
    from tsa_bench.simavr import SimavrBench, SimavrError
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
@click.argument("protocol", type=click.Path(dir_okay=False), required=False)
@click.option("--bench", "bench_path", type=click.Path(dir_okay=False), default=None,
              help="Bench file (default: configs/bench/sim.yaml, the simulated bench; with a serial --port, "
                   "configs/bench/arduino-mega.yaml).")
@click.option("--port", default=None, help="Serial device (or sim://); overrides the bench file's backend.")
@click.option("--out", "out_dir", default="runs", show_default=True, help="Directory for the run file.")
@click.option("--output", "out_file", type=click.Path(dir_okay=False), default=None,
              help="Exact run-file path (overrides --out).")
@click.option("--speed", type=float, default=None,
              help="Simulated benches only: real-time factor (1 = wall-clock pace); default as fast as possible.")
@click.option("--seed", type=int, default=None, help="Simulated bench only: noise seed.")
@click.option("--meta", "metas", multiple=True, metavar="KEY=VALUE",
              help="Stored in the run's metadata, e.g. --meta operator=ana --meta sample=S3 (repeatable).")
@click.option("--resume", "resume_file", type=click.Path(dir_okay=False), default=None,
              help="Continue this aborted, failed or killed run from its first incomplete segment, into a new "
                   "file linked to it (default name: RUN-resumed.h5 beside it).")
@SET_OPTION
@CATALOGUE_OPTION
@click.option("--operator-socket", "operator_fd", type=int, default=None, hidden=True,
              help="(tsa-bench lab) a socket descriptor the lab supervisor answers operator prompts on.")
@ALLOW_URL
@TRUST_FW
@MAX_MEMORY
def run(protocol: str | None, bench_path: str | None, port: str | None, out_dir: str, out_file: str | None,
        speed: float | None, seed: int | None, metas: tuple[str, ...], resume_file: str | None, sets: tuple[str, ...],
        catalogue_url: str | None, operator_fd: int | None, allow_url: bool, trust_firmware_dir: bool) -> None:
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
    session: dict = {}
    try:
        with interrupts.immediate():
            _prepare_run(session, protocol, bench_path, port, out_dir, out_file, speed, seed, metas, resume_file,
                         allow_url, trust_firmware_dir, sets)
            session.update(catalogue=catalogue_url, operator_fd=operator_fd)
        code = _execute_run(session, interrupts)
    except KeyboardInterrupt:
        click.echo("aborted before the run started; nothing was run", err=True)
        code = EXIT_ABORTED
    finally:
        if "path" in session:
            release_run_file(session["path"])
        if interrupts.requested:
            # Exiting 130: a further signal must not change that, nor kill the process
            # while Python shuts down (it puts default handlers back, but keeps SIG_IGN).
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, signal.SIG_IGN)
        else:
            interrupts.restore()
    sys.exit(code)


def _close_registry(registry, resume) -> None:
    """Last: the outcome is on the screen while the catalogue is written."""
    if registry is not None:
        if resume is not None:
            registry.refresh(resume.source)   # its file now names this continuation
        registry.close()


def _check_simulation_options(port: str | None, bench, speed: float | None, seed: int | None) -> None:
    """--speed and --seed only mean something to a simulation this process runs."""
    serial = is_serial_port(port) or (port is None and bench.backend == "serial")
    if serial and speed is not None:
        fail(f"--speed applies only to a simulated bench this command runs (sim://, simavr); {port or bench.port} "
             "is a serial device, which runs in real time (give --speed to `tsa-bench sim-serve` instead)")
    if serial and seed is not None:
        fail(f"--seed applies only to a simulated bench this command runs (sim://, simavr); the device on "
             f"{port or bench.port} has no noise seed (give --seed to `tsa-bench sim-serve` instead)")
    if speed is not None and not (speed > 0 and speed < float("inf")):
        fail("--speed must be > 0 (a real-time factor)")


def _prepare_run(session: dict, protocol, bench_path, port, out_dir, out_file, speed, seed, metas, resume_file,
                 allow_url, trust_firmware_dir, sets=()) -> None:
    """Everything that can be refused before anything is opened: bench, protocol, port,
    output path (reserved: ``session["path"]``), free space; fills ``session``. Exits 2 (bad
    input) or 1 (no room) with nothing sent."""
    from tsa_bench.store.space import StorageFull, ensure_room, run_bytes

    check_port_or_exit(port, allow_url)
    meta: dict = meta_pairs(metas)
    variables = variable_values(sets)
    if variables:
        meta["protocol_variables"] = variables   # kept in the run file: --resume compiles the same plan
    resume = None
    if resume_file is not None:
        if protocol is not None or variables:
            fail("give either PROTOCOL or --resume RUN.h5 (a resumed run uses the protocol and the --set "
                 "variables stored in RUN.h5)")
        from tsa_bench.cli.resume import prepare_resume

        bench, plan, resume, bench_file, variables, resume_file = prepare_resume(
            resume_file, bench_path, port, allow_url, trust_firmware_dir)
        if variables:
            meta["protocol_variables"] = variables   # the continuation compiles as the run it continues
    else:
        if protocol is None:
            fail("missing PROTOCOL (a protocol YAML file), or --resume RUN.h5")
        bench = load_bench_or_exit(bench_path, port, allow_url=allow_url, trust_firmware_dir=trust_firmware_dir)
        plan = load_plan_or_exit(protocol, bench, variables)
        bench_file = bench.path
    _check_simulation_options(port, bench, speed, seed)
    path = session["path"] = reserve_run_file(out_dir, plan.name, out_file, resume_file if resume else None)
    summary = plan.summary()
    period_s = min(plan.sampling_period_s, summary.sampling_period_range_s[0] or plan.sampling_period_s)
    try:
        ensure_room(path, run_bytes(summary.duration_s / period_s, len(plan.segments)), "this run")
    except StorageFull as exc:
        fail(f"{exc}; free some space or choose another --out; nothing was run", EXIT_FAILED)
    session.update(bench=bench, bench_file=bench_file, plan=plan, port=port, path=path, speed=speed, seed=seed,
                   meta=meta, resume=resume, trust_firmware_dir=trust_firmware_dir)


def _open(session: dict):
    """(url, backend word, simavr bench or None): the port this run opens; prints the banner."""
    bench, plan, port = session["bench"], session["plan"], session["port"]
    speed, seed = session["speed"], session["seed"]
    if port is None and bench.backend == "sim":
        from tsa_bench.transport.protocol_sim import hand_over_bench

        hand_over_bench(bench)   # the sim:// port uses it: the file is not loaded and checked twice
        click.echo(f"tsa-bench: running '{plan.name}' on the SIMULATED bench ({bench.name}); no hardware is used")
        return _sim_url(session["bench_file"], speed, seed), None
    if port is None and bench.backend == "simavr":
        fil = _start_simavr(bench, speed, seed, session["trust_firmware_dir"])
        click.echo(f"tsa-bench: running '{plan.name}' on the firmware in simavr ({bench.name}); no hardware is used")
        return fil.port_path, fil
    url = port or bench.port
    if not url:
        fail(f"{bench.path}: backend is serial but no port is given (use --port)")
    click.echo(f"tsa-bench: running '{plan.name}' on {url} at {bench.baud} baud ({bench.name})")
    return url, None


def _progress_can_show() -> bool:
    """Whether the live progress line may show: stderr is a terminal, or the environment says
    to treat it as one (rich's own test decides then). Otherwise no display is made, so rich
    is not imported for it."""
    if os.environ.get("TTY_COMPATIBLE") is not None or os.environ.get("FORCE_COLOR") is not None:
        return True
    try:
        return sys.stderr.isatty()
    except ValueError:
        return False


def _execute_run(session: dict, interrupts) -> int:
    """Open the bench, run, summarise; return the exit code."""
    import serial

    from tsa_bench import transport  # noqa: F401  (registers the sim:// URL handler)
    from tsa_bench.console.summary import format_run_info
    from tsa_bench.device import BenchClient, DeviceError
    from tsa_bench.protocol import msg
    from tsa_bench.operator import AutoOperator
    from tsa_bench.operator.terminal import TerminalOperator
    from tsa_bench.runner import PlanRejected, Runner, check_plan_against_device
    from tsa_bench.store import RunFileError, RunWriter
    from tsa_bench.store.inspect import inspect_run

    bench, plan, path, resume = session["bench"], session["plan"], session["path"], session["resume"]
    fil = None  # firmware in the loop (simavr)
    with interrupts.immediate():
        url, fil = _open(session)
        click.echo(f"run file     {path}   (live view: tsa-bench watch {path})")
        sys.stdout.flush()
        try:
            ser = serial.serial_for_url(url, baudrate=bench.baud, timeout=0.05, write_timeout=2.0)
        except (serial.SerialException, ValueError, OSError) as exc:
            if fil is not None:
                fil.close()
            fail(f"cannot open {url}: {exc}\n  check the device is plugged in, the port name "
                 "(`tsa-bench ports`), and that no other program holds it", EXIT_FAILED)
    writer = registry = None
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
            simulated = bool(ident.flags & msg.DeviceFlags.SIMULATED)
            if fil is not None:
                backend = "simavr"
            elif simulated:
                backend = "sim"
            else:
                backend = "serial"
                if bench.plant:
                    fail(f"{bench.path} describes a simulated bench (it has a plant section) but the device on "
                         f"{url} is real hardware: use a serial bench file such as configs/bench/arduino-mega.yaml "
                         "(or your calibrated copy); nothing was run")
            person = _person(session, TerminalOperator)
            operator = AutoOperator(say=person.tell) if simulated else person
            if resume is not None and not simulated:
                _confirm_resume(resume, person)
            writer = RunWriter(path, live=True, reserved=True)   # it keeps the run's journal RUN.h5.live
            if fil is not None:
                from tsa_bench.simavr.operator import PlantOperator
                operator = PlantOperator(fil, say=person.tell)
                operator.apply_initial(plan.load_g if resume is None else resume.load_g)
        consumers = [writer]
        registry = _registry(session)
        if registry is not None:
            consumers.append(registry)
        if _progress_can_show():
            from tsa_bench.console.progress import ProgressDisplay

            display = ProgressDisplay()
            consumers.append(display)
            person.hold(display)   # off the screen while a person is asked
        runner = Runner(client, plan, bench, consumers, operator, backend=backend, port_name=url,
                        interrupts=interrupts, resume=resume, metadata=session["meta"])
        stop = runner.run()
        if stop.exit_status == "success" and not simulated:
            client.arm_reset()   # the next open resets the Mega: keep the position across that reset
    finally:
        ser.close()
        if fil is not None:
            fil.close()
            _report_simavr(fil)
    if writer is not None and writer.broken:
        # The HDF5 library failed a write: its state is broken and it would crash on exit.
        click.echo(f"error: run failed: {writer.broken}; the run's journal {path}.live holds every sample: "
                   f"tsa-bench run --resume {path} (or tsa-bench info {path}) rebuilds the run from it", err=True)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(EXIT_FAILED)
    recorded = path.is_file() and path.stat().st_size > 0   # the reservation stays empty if nothing started
    if recorded:
        try:  # the writer's running statistics: the file is not read back
            info = writer.summary() if writer is not None and writer.stats.n else inspect_run(path)
            click.echo(format_run_info(info))
        except RunFileError as exc:
            click.echo(f"error: {exc}", err=True)
        if resume is not None:
            from tsa_bench.store.links import link_continuation

            note = link_continuation(resume.source, path)
            if note:
                click.echo(f"warning: {note}", err=True)
    rtf = stop.t_end / stop.wall_time_s if stop.wall_time_s > 0 else float("inf")
    click.echo(f"wall time    {stop.wall_time_s:.2f} s (real-time factor {rtf:.0f})")
    if stop.exit_status != "success" or (writer is not None and writer.full):
        reason = writer.full if writer is not None and writer.full and stop.exit_status == "success" else stop.reason
        status = "failed" if stop.exit_status == "success" else stop.exit_status
        click.echo(f"run {status}: {reason}", err=True)
        if status != "success":
            click.echo(f"  {_next_step(stop, path, resume)}", err=True)
    if writer is not None and writer.close_error:
        click.echo(f"error: the run file could not be closed properly: {writer.close_error}; it is marked failed "
                   f"and the run's journal {path}.live is kept (tsa-bench run --resume {path} rebuilds the run "
                   "from it)", err=True)
        _close_registry(registry, resume)
        return EXIT_FAILED
    click.echo(f"wrote {path}" if recorded else f"no run file was written ({path})")
    sys.stdout.flush()
    _close_registry(registry, resume)
    if writer is not None and writer.full and stop.exit_status == "success":
        return EXIT_FAILED
    return {"success": 0, "aborted": EXIT_ABORTED}.get(stop.exit_status, EXIT_FAILED)


def _next_step(stop, path: Path, resume) -> str:
    """What to do after a run that did not succeed: resume it, or (nothing was done) run it again."""
    if stop.segments_done == 0:
        again = f"the same command again (it resumes {resume.source})" if resume is not None else "it again"
        return f"no segment was done: fix the cause above and run {again}; {path} records the attempt"
    return f"to continue it later: tsa-bench run --resume {path}"


def _registry(session: dict):
    """The catalogue consumer of this run (None with --catalogue none)."""
    from tsa_bench.cli.catalogue import recorder

    kind = "resumed" if session["resume"] is not None else "recorded"
    plan = session["plan"]
    return recorder(session.get("catalogue"), session["path"], kind=kind, load_g=plan.load_g)


def _person(session: dict, terminal):
    """Who answers a real rig's prompts: the lab supervisor (``--operator-socket``) or the terminal."""
    if session.get("operator_fd") is None:
        return terminal()
    from tsa_bench.lab.channel import RigChannel

    try:
        return RigChannel.from_fd(session["operator_fd"])
    except OSError as exc:
        fail(f"--operator-socket {session['operator_fd']}: {exc.strerror or exc}; nothing was run")


def _confirm_resume(resume, person) -> None:
    """On a real rig a person confirms the rig is ready for the resumed segment."""
    from tsa_bench.operator import OperatorAbsent

    load = "" if resume.load_g is None else f"; hang {resume.load_g:g} g"
    person.tell(f"tsa-bench: {resume.describe()}")
    try:
        yes = person.confirm(f"The motor will move to {resume.turns:g} turns from where the device is now{load}. "
                             "Continue?", if_no="nothing is run")
    except OperatorAbsent as exc:
        fail(f"{exc}; nothing was run")
    if not yes:
        fail("not confirmed; nothing was run")
