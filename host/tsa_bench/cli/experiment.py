"""Experiment commands: `tsa-bench validate | sim-serve | effects` (`run` is in :mod:`.run`).

Exit codes as in :mod:`tsa_bench.cli`.
"""

from __future__ import annotations

import sys
import threading

import click

from tsa_bench.cli.exits import fail

from tsa_bench.cli.loading import (
    ALLOW_URL, SET_OPTION, TRUST_FW, check_port_or_exit, load_bench_or_exit, load_plan_or_exit, variable_values,
)


@click.command()
@click.argument("protocol", type=click.Path(dir_okay=False))
@click.option("--bench", "bench_path", type=click.Path(dir_okay=False), default=None,
              help="Bench file (default: configs/bench/sim.yaml, the simulated bench; with a serial --port, "
                   "configs/bench/arduino-mega.yaml).")
@click.option("--port", default=None, help="Serial device the run would use (checked like `run --port`).")
@SET_OPTION
@ALLOW_URL
@TRUST_FW
def validate(protocol: str, bench_path: str | None, port: str | None, sets: tuple[str, ...], allow_url: bool,
             trust_firmware_dir: bool) -> None:
    """Check PROTOCOL and the bench file as `run` would (schema, limits, device commands, plant);
    print the compiled plan."""
    from tsa_bench.plan import format_summary

    check_port_or_exit(port, allow_url)
    bench = load_bench_or_exit(bench_path, port, allow_url=allow_url, trust_firmware_dir=trust_firmware_dir)
    plan = load_plan_or_exit(protocol, bench, variable_values(sets))
    click.echo(format_summary(plan))
    click.echo(f"valid for bench '{bench.name}'")


@click.command()
@click.option("--bench", "bench_path", type=click.Path(dir_okay=False), default=None,
              help="Also show which effects this simulated bench switches on and its values.")
def effects(bench_path: str | None) -> None:
    """List the simulated plant's physical effects with their parameters, units and defaults."""
    from tsa_bench.sim.effects import describe_effects

    configured: dict = {}
    if bench_path is not None:
        bench = load_bench_or_exit(bench_path, allow_url=True, trust_firmware_dir=True)  # only shown
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
@click.option("--as-hardware", is_flag=True,
              help="Rehearse the rig: the device does not say it is simulated (every question a real rig "
                   "asks is asked), resets when a client opens the port (as a Mega's DTR does), powers up "
                   "with its position unknown, and changes its load only when you type one here "
                   "(grams, then Enter).")
@click.option("--no-reset-on-open", "no_reset", is_flag=True,
              help="With --as-hardware: a Mega wired not to reset when the port opens (a latched fault "
                   "then outlives the program that caused it).")
def sim_serve(bench_path: str | None, speed: float | None, seed: int | None, as_hardware: bool,
              no_reset: bool) -> None:
    """Serve the simulated bench on a pseudo-terminal; prints its path, runs until Ctrl-C."""
    import queue

    from tsa_bench.transport.pty_server import serve_pty

    if no_reset and not as_hardware:
        fail("--no-reset-on-open goes with --as-hardware")
    bench = load_bench_or_exit(bench_path)
    loads: queue.SimpleQueue[float] | None = queue.SimpleQueue() if as_hardware else None

    def ready(path: str) -> None:
        click.echo(path)
        if as_hardware:
            load = float((bench.plant or {}).get("initial_load_g", 500))
            click.echo(f"rehearsal rig '{bench.name}' on {path}: it passes for hardware (no SIMULATED flag); "
                       f"{'' if no_reset else 'it resets when a program opens the port; '}it powers up with its "
                       f"position unknown and {load:g} g hanging."
                       f"\n  run: tsa-bench run PROTOCOL --bench arduino-mega.yaml --port {path}"
                       "\n  hang a load: type its mass in grams here and press Enter (Ctrl-C stops)", err=True)
            threading.Thread(target=_read_loads, args=(loads,), daemon=True).start()
        else:
            click.echo(f"simulated bench '{bench.name}' serving on {path}; "
                       f"run: tsa-bench run PROTOCOL --bench {bench.path} --port {path}   (Ctrl-C stops)", err=True)
        sys.stdout.flush()

    def reset(device) -> None:
        kept = "position kept" if device.position_known else "position unknown"
        click.echo(f"rig: reset (port opened): {kept}", err=True)

    def fault(code: int) -> None:
        from tsa_bench.device.faults import fault_name

        click.echo(f"rig: fault {fault_name(code)} latched" if code else "rig: fault cleared", err=True)

    try:
        serve_pty(bench, speed, seed, ready, as_hardware=as_hardware, reset_on_open=not no_reset, loads=loads,
                  on_reset=reset, on_fault=fault if as_hardware else None)
    except KeyboardInterrupt:
        pass


def _read_loads(loads) -> None:
    """Lines typed at the rehearsal rig: a mass in grams hangs that load."""
    for line in sys.stdin:
        text = line.strip().lower().removesuffix("g").strip()
        if not text:
            continue
        try:
            grams = float(text)
        except ValueError:
            click.echo(f"rig: {line.strip()!r} is not a mass in grams (type e.g. 350 and Enter)", err=True)
            continue
        if not 0 <= grams < 1e6:
            click.echo(f"rig: {grams:g} g cannot hang here (0 to 1e6 g)", err=True)
            continue
        loads.put(grams)
        click.echo(f"rig: {grams:g} g hanging now", err=True)
