"""What several commands read first: the bench file, the protocol, the port; each
refused with a one-line error (exit 2) before anything is opened or sent.

Bench file when none is given: the simulated bench (``configs/bench/sim.yaml``) without
a port or with ``sim://``, the Arduino Mega bench (``configs/bench/arduino-mega.yaml``)
with a serial port, which is said on stderr. Paths are looked up as documented in
:mod:`tsa_bench.shipped` (the shipped configs when not found as given).
"""

from __future__ import annotations

from pathlib import Path

import click

from tsa_bench.cli.exits import fail

SIM_BENCH, MEGA_BENCH = "sim.yaml", "arduino-mega.yaml"

ALLOW_URL = click.option("--allow-url", is_flag=True,
                         help="Allow any pyserial URL as the port (spy://, socket://, ...); by default only serial "
                              "device paths and sim:// are allowed.")
TRUST_FW = click.option("--trust-firmware-dir", is_flag=True,
                        help="Let a simavr bench build firmware in a folder other than this project's firmware/.")


def FORCE(command):  # noqa: N802 (a decorator, named like the options above)
    """``--force``: the command may replace output files that exist (never through a link:
    the link itself is replaced); without it an existing output is refused (exit 2)."""
    import functools

    @functools.wraps(command)
    def wrapper(*args, force: bool, **kwargs):
        from tsa_bench.outputs import OutputExists, replace_allowed

        with replace_allowed(force):
            try:
                return command(*args, force=force, **kwargs)
            except OutputExists as exc:   # appeared while the command worked
                fail(str(exc))

    return click.option("--force", is_flag=True,
                        help="Replace output files that exist (a link there is replaced, never written "
                             "through); without it an existing output is refused.")(wrapper)


def _set_max_memory(ctx: click.Context, param: click.Parameter, value: str | None) -> None:
    if value is None:
        return
    from tsa_bench.store.budget import parse_size, set_memory_budget

    try:
        set_memory_budget(parse_size(value))
    except ValueError as exc:
        raise click.BadParameter(str(exc), ctx, param) from None


MAX_MEMORY = click.option("--max-memory", metavar="SIZE", default=None, expose_value=False, is_eager=True,
                          callback=_set_max_memory,
                          help="Memory budget for reading files (e.g. 8G; default: 4 GiB or half the machine's "
                               "memory, or $TSA_BENCH_MAX_MEMORY): a file declaring more data is refused unread.")


def is_serial_port(port: str | None) -> bool:
    """A port naming a serial device (not the simulated bench's sim://)."""
    return port is not None and not port.lower().startswith("sim://")


def bench_path(path: str | None, port: str | None = None, *, say: bool = True) -> Path:
    """The bench file to read: ``path`` (searched), else the default for ``port``."""
    from tsa_bench.shipped import find_config, shipped

    if path is None:
        if is_serial_port(port):
            default = shipped(f"bench/{MEGA_BENCH}")
            if say:
                click.echo(f"tsa-bench: no --bench given for the serial port {port}: using the Arduino Mega bench "
                           f"file {default} (pass --bench with your calibrated copy)", err=True)
            return default
        return shipped(f"bench/{SIM_BENCH}")
    found, from_shipped = find_config(path, "bench")
    if from_shipped and say:
        click.echo(f"tsa-bench: {path} is not in the current folder: using the shipped {found}", err=True)
    return found


def load_bench_or_exit(path: str | None, port: str | None = None, *, allow_url: bool = False,
                       trust_firmware_dir: bool = False, say: bool = True):
    """The validated bench file (see :func:`bench_path`), or exit 2 with its error."""
    from tsa_bench.bench import BenchConfigError, load_bench

    try:
        return load_bench(bench_path(path, port, say=say), allow_url=allow_url,
                          trust_firmware_dir=trust_firmware_dir)
    except BenchConfigError as exc:
        fail(str(exc))


SET_OPTION = click.option(
    "--set", "sets", multiple=True, metavar="NAME=VALUE",
    help="Give a variable the protocol declares another value, e.g. --set load_g=350 (repeatable).")


def variable_values(values: tuple[str, ...]) -> dict[str, int | float | str]:
    """``NAME=VALUE`` pairs of ``--set``: a number stays a number; exit 2 if malformed."""
    out: dict[str, int | float | str] = {}
    for name, text in meta_pairs(values, "--set").items():
        try:
            number = float(text)
            out[name] = int(number) if number.is_integer() and "." not in text and "e" not in text.lower() else number
        except ValueError:
            if not text.strip():
                fail(f"--set {name}=: give a value")
            out[name] = text
        if isinstance(out[name], float) and out[name] != out[name] or out[name] in (float("inf"), float("-inf")):
            fail(f"--set {name}={text}: not a finite number")
    return out


def load_plan_or_exit(path: str, bench, variables: dict | None = None):
    """The protocol, compiled under the bench limits (``variables`` replacing declared values),
    with every device command checked to fit the wire: `validate` and `run` refuse exactly
    the same protocols."""
    from tsa_bench.plan import PlanErrors, load_plan
    from tsa_bench.runner.commands import plan_problems
    from tsa_bench.shipped import find_config

    found, from_shipped = find_config(path, "protocols")
    if from_shipped:
        click.echo(f"tsa-bench: {path} is not in the current folder: using the shipped {found}", err=True)
    try:
        plan = load_plan(found, bench.limits, variables)
    except PlanErrors as exc:
        fail(f"{found} is not a valid protocol; nothing was sent to any device:\n{exc}")
    from tsa_bench.runner.tracking import bench_problems

    problems = plan_problems(plan, bench.steps_per_turn) + bench_problems(plan, bench.name)
    if problems:
        fail(f"{found} cannot be sent to bench '{bench.name}'; nothing was sent to any device:\n"
             + "\n".join(problems))
    return plan


def check_port_or_exit(port: str | None, allow_url: bool) -> None:
    from tsa_bench.bench.ports import PortPolicyError, check_port

    if port is not None:
        try:
            check_port(port, allow_url=allow_url)
        except PortPolicyError as exc:
            fail(f"--port: {exc}")


def meta_pairs(values: tuple[str, ...], option: str = "--meta") -> dict[str, str]:
    """``KEY=VALUE`` pairs, one per option use (the value may hold commas or '='); exit 2 if malformed."""
    out: dict[str, str] = {}
    for item in values:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            fail(f"{option}: '{item}' is not KEY=VALUE")
        if any(ch in item for ch in "\x00\r\n"):
            fail(f"{option}: '{key.strip()}' holds a control character")
        out[key.strip()] = value
    return out
