"""Experiment commands: `tsa-bench validate | sim-serve | effects` (`run` is in :mod:`.run`).

Exit codes as in :mod:`tsa_bench.cli`.
"""

from __future__ import annotations

import sys

import click

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
def sim_serve(bench_path: str | None, speed: float | None, seed: int | None) -> None:
    """Serve the simulated bench on a pseudo-terminal; prints its path, runs until Ctrl-C."""
    from tsa_bench.transport.pty_server import serve_pty

    bench = load_bench_or_exit(bench_path)

    def ready(path: str) -> None:
        click.echo(path)
        click.echo(f"simulated bench '{bench.name}' serving on {path}; "
                   f"run: tsa-bench run PROTOCOL --bench {bench.path} --port {path}   (Ctrl-C stops)", err=True)
        sys.stdout.flush()

    try:
        serve_pty(bench, speed, seed, ready)
    except KeyboardInterrupt:
        pass

