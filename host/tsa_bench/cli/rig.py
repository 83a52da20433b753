"""Rig commands: `tsa-bench ports | check | jog | calibrate position|resistance`
(and `zero`, in :mod:`.zero`).

Exit codes as in :mod:`tsa_bench.cli`: 0 done, 1 the device could not be reached or
reported a problem, 2 bad input (nothing was sent), 130 aborted.
"""

from __future__ import annotations

import os
import sys
from contextlib import contextmanager
from pathlib import Path

import click

from tsa_bench.cli.exits import EXIT_ABORTED, EXIT_FAILED, fail
from tsa_bench.cli.loading import ALLOW_URL, check_port_or_exit, load_bench_or_exit

_PORT = click.option("--port", default=None,
                     help="Serial device (or sim://); default: the bench file's port.")
_BENCH = click.option("--bench", "bench_path", type=click.Path(dir_okay=False), default=None,
                      help="Bench file (default: configs/bench/arduino-mega.yaml with a serial port, "
                           "configs/bench/sim.yaml with sim://).")


def _rig(port: str | None, bench_path: str | None, allow_url: bool):
    """(bench, port to open) or exit 2."""
    check_port_or_exit(port, allow_url)
    bench = load_bench_or_exit(bench_path, port, allow_url=allow_url, trust_firmware_dir=True)
    url = port or bench.port
    if url is None and bench.backend == "sim":
        import urllib.parse
        url = "sim://?" + urllib.parse.urlencode({"bench": str(Path(bench.path).resolve())})
    if not url:
        fail("no port: give --port (tsa-bench ports lists the serial ports) or a bench file with a port")
    return bench, url


@contextmanager
def _open_or_exit(url: str, bench, *, clear: bool = True):
    """The open rig (:func:`tsa_bench.rig.link.open_link`), a fault latched before this command
    cleared after saying so (unless ``clear`` is False); a device error anywhere inside (a
    refusal, a stall without acknowledgement, a lost port) ends the command with one line,
    exit 1. A caller that must keep something first catches the error itself and re-raises."""
    from tsa_bench.device import DeviceError
    from tsa_bench.rig.link import RigError, open_link

    try:
        with open_link(url, bench) as link:
            if clear:
                link.clear_fault(lambda text: click.echo(f"warning: {text}", err=True))
            yield link
    except (RigError, DeviceError) as exc:
        fail(str(exc), EXIT_FAILED)


@click.command()
@click.option("--probe", is_flag=True, help="Also open each likely board and try the tsa-bench handshake "
                                           "(this resets a Mega).")
@click.option("--also", "extra", multiple=True, metavar="PATH",
              help="Another port to list and probe (a pseudo-terminal from sim-serve, say); repeatable.")
@_BENCH
@ALLOW_URL
def ports(probe: bool, extra: tuple[str, ...], bench_path: str | None, allow_url: bool) -> None:
    """List serial ports with their USB ids; mark the likely Arduino Megas."""
    from tsa_bench.rig.ports import PortInfo, likely_board, list_ports, probe as do_probe

    found = list_ports()
    for path in extra:
        check_port_or_exit(path, allow_url)
        found.append(PortInfo(path, "given with --also"))
    if not found:
        click.echo("no serial ports found. Plug the Mega in with a data USB cable; on Linux check `dmesg` and "
                   "that you are in the dialout group (README: A real Arduino Mega).")
    for p in found:
        level, text = likely_board(p)
        mark = {2: "MEGA ", 1: "maybe", 0: "     "}[level]
        usb = f"USB {p.usb_id}" if p.usb_id else "no USB id"
        serial = f"  serial {p.serial_number}" if p.serial_number else ""
        click.echo(f"{mark}  {p.device}  {usb}{serial}  {p.description}" + (f"  ({text})" if text else ""))
    if probe:
        bench = load_bench_or_exit(bench_path, "/dev/null", allow_url=allow_url, trust_firmware_dir=True, say=False)
        for p in found:
            if likely_board(p)[0] or p.device in extra:
                r = do_probe(p.device, bench)
                click.echo(f"probe  {p.device}: {'OK, ' if r.ok else 'no: '}{r.text}")


@click.command()
@_PORT
@_BENCH
@click.option("--seconds", type=click.FloatRange(0.1, 3600), default=2.0, show_default=True,
              help="How long to read the sensors (device time).")
@click.option("--period", "period_s", type=click.FloatRange(0.001, 60), default=0.1, show_default=True,
              help="Sampling period (s).")
@click.option("--live", is_flag=True, help="Print every sample (raw and converted) as it arrives.")
@ALLOW_URL
def check(port: str | None, bench_path: str | None, seconds: float, period_s: float, live: bool,
          allow_url: bool) -> None:
    """Identity, firmware and catalogue, fault state, and the sensors raw and converted.

    Nothing moves and the heater stays off. A fault latched before the check is shown
    (what, since when, what to do) and cleared; an unknown twist zero is reported. Exit 1
    when the device cannot be reached, a fault stays latched or a sensor never gives a
    valid reading.
    """
    from tsa_bench.device.faults import fault_name
    from tsa_bench.protocol import msg
    from tsa_bench.rig.check import check_rig, findings
    from tsa_bench.rig.link import RigError

    bench, url = _rig(port, bench_path, allow_url)

    def show(s) -> None:
        length = bench.position.length_mm(s.position_raw)
        res = "not measured" if s.adc_flags & msg.AdcFlags.RESISTANCE_NOT_MEASURED else \
            f"{bench.resistance.resistance_ohm(s.resistance_raw):.5f} ohm"
        click.echo(f"sample {s.counter}: position {s.position_raw} counts = {length:.3f} mm   resistance "
                   f"{s.resistance_raw} counts = {res}   flags {s.adc_flags}   step {s.step_position}")

    try:
        with _open_or_exit(url, bench, clear=False) as link:
            ident = link.identity
            click.echo(f"device       {url}: {'SIMULATED ' if link.simulated else ''}tsa-bench firmware "
                       f"{ident.fw_major}.{ident.fw_minor}.{ident.fw_patch}, protocol v{ident.protocol_version}, "
                       f"catalogue 0x{ident.catalogue_hash:08X} (matches this host)")
            click.echo(f"limits       twist {ident.min_twist_steps / ident.steps_per_turn:g}.."
                       f"{ident.max_twist_steps / ident.steps_per_turn:g} turns at {ident.steps_per_turn} steps/turn, "
                       f"heater <= {ident.max_heater_mV / 1000:g} V, watchdog {ident.watchdog_ms} ms, "
                       f"queue {ident.queue_slots}")
            cleared = link.clear_fault(lambda text: click.echo(f"fault        {text}"))
            rep = check_rig(link, seconds, period_s, show if live else None)
    except RigError as exc:
        fail(str(exc), EXIT_FAILED)
    fault = msg.Fault(rep.status.fault).name.lower() if rep.status.fault else "none"
    if cleared is not None and not rep.status.fault:
        fault = f"none ({fault_name(cleared.fault)} cleared above)"
    twist = "unknown (no twist zero: tsa-bench zero)" if rep.position_unknown else f"{rep.twist_turns:g} turns"
    click.echo(f"state        fault {fault}, twist {twist}, heater {rep.heater_V:g} V")
    click.echo(f"samples      {rep.samples} over {rep.duration_s:.2f} s")
    for st, raw_unit in ((rep.length, "counts"), (rep.resistance, "counts")):
        if st.valid:
            click.echo(f"{st.name:<12} {st.mean:.5g} {st.unit} (raw {st.raw_mean:.1f} {raw_unit}); "
                       f"{st.lo:.5g}..{st.hi:.5g}, std {st.std:.3g} {st.unit}; {st.valid}/{st.total} valid")
        else:
            click.echo(f"{st.name:<12} no valid reading ({st.total} samples)")
    problems = findings(rep, cleared=cleared)
    for p in problems:
        click.echo(f"warning: {p}", err=True)
    hard = rep.status.fault or not rep.length.valid or not rep.resistance.valid
    if hard:
        verdict = "FAILED"
    elif rep.position_unknown:
        verdict = "position unknown, sensors read (see the warnings)"
    else:
        verdict = "ok" + (" (see the warnings)" if problems else "")
    click.echo(f"check: {verdict}")
    sys.exit(EXIT_FAILED if hard else 0)


class _Keys:
    """Single key presses from a terminal (cbreak mode), restored on exit."""

    def __enter__(self):
        import termios
        import tty

        self.fd = sys.stdin.fileno()
        self.saved = termios.tcgetattr(self.fd)
        tty.setcbreak(self.fd)
        return self

    def __exit__(self, *exc) -> None:
        import termios

        termios.tcsetattr(self.fd, termios.TCSADRAIN, self.saved)

    def key(self, timeout_s: float) -> str | None:
        import select

        ready, _, _ = select.select([self.fd], [], [], timeout_s)
        return os.read(self.fd, 1).decode(errors="replace") if ready else None


KEY_HELP = ("keys: + / - twist by the step, [ ] halve / double the step, < > halve / double the rate, "
            "0 back to 0 turns, h heater on/off, any key during a move: STOP, q quit")


@click.command()
@_PORT
@_BENCH
@click.option("--out", "out_dir", default="runs", show_default=True, help="Directory for the session's run file.")
@click.option("--output", "out_file", type=click.Path(dir_okay=False), default=None, help="Exact run-file path.")
@click.option("--script", "script", type=click.Path(dir_okay=False, allow_dash=True), default=None,
              help="Run the commands in this file (- for stdin) instead of keys; see the command list below.")
@click.option("--step", "step_turns", type=click.FloatRange(0.001, 1000), default=1.0, show_default=True,
              help="Twist per key press (turns).")
@click.option("--rate", "rate", type=click.FloatRange(0.001, 1000), default=1.0, show_default=True,
              help="Motor rate (turns/s).")
@click.option("--heater-V", "heater_V", type=click.FloatRange(0, 1000), default=2.0, show_default=True,
              help="Heater voltage of the h key (V).")
@click.option("--heater-timeout", "heater_timeout_s", type=click.FloatRange(0.1, 86400), default=30.0,
              show_default=True, help="The heater switches itself off after this long (s).")
@ALLOW_URL
def jog(port, bench_path, out_dir, out_file, script, step_turns, rate, heater_V, heater_timeout_s, allow_url) -> None:
    """Move the motor and switch the heater by hand; the session is recorded as a run file.

    \b
    Script commands, one per line:  +N | -N (twist by N turns)   to N (twist to N turns)
    rate N (turns/s)   heater V | heater off   wait S   stop   quit
    """
    from tsa_bench.cli.run import release_run_file, reserve_run_file
    from tsa_bench.device import DeviceError
    from tsa_bench.rig.jog import JogError, JogSession, parse_command
    from tsa_bench.rig.link import RigError
    from tsa_bench.store import RunWriter

    bench, url = _rig(port, bench_path, allow_url)
    limit = bench.limits.max_rate_turns_per_s
    if limit is not None and rate > limit:
        fail(f"--rate {rate:g} turns/s is above the bench's {limit:g} turns/s")
    lines = None
    if script is not None:
        text = sys.stdin.read() if script == "-" else Path(script).read_text(encoding="utf-8", errors="replace")
        lines = text.splitlines()
        try:
            for i, line in enumerate(lines):
                parse_command(line)
        except JogError as exc:
            fail(f"{script}:{i + 1}: {exc}")
    elif not sys.stdin.isatty():
        fail("jog reads keys from a terminal; give --script FILE (or --script -) to run commands instead")
    path = reserve_run_file(out_dir, "jog", out_file)   # exclusively: concurrent sessions get their own names
    click.echo(f"run file     {path}")
    status, reason = "success", "session ended by the operator"
    try:
        with _open_or_exit(url, bench) as link:
            backend = "sim" if link.simulated else "serial"
            note = link.require_position()
            if note:
                click.echo(note)
            session = JogSession(link, [RunWriter(path, live=True, reserved=True)], rate_turns_per_s=rate,
                                 heater_timeout_s=heater_timeout_s, backend=backend, say=click.echo)
            session.start()
            try:
                if lines is not None:
                    _run_script(session, lines, parse_command, JogError)
                else:
                    _run_keys(session, step_turns, heater_V, JogError)
            except KeyboardInterrupt:
                status, reason = "aborted", "interrupted by the user (Ctrl-C)"
            except (RigError, DeviceError) as exc:
                status, reason = "failed", str(exc)
            finally:
                session.finish(status, reason)
    except RigError as exc:
        fail(str(exc), EXIT_FAILED)
    finally:
        release_run_file(path)   # nothing recorded (the link failed): the reserved name is given back
    if status == "failed":
        click.echo(f"error: {reason}", err=True)
    click.echo(f"wrote {path}")
    sys.exit({"success": 0, "aborted": EXIT_ABORTED}.get(status, EXIT_FAILED))


def _run_script(session, lines, parse_command, JogError) -> None:
    for i, line in enumerate(lines):
        cmd = parse_command(line)
        if cmd is None:
            continue
        try:
            if not session.execute(cmd):
                break
        except JogError as exc:
            click.echo(f"line {i + 1}: {exc}", err=True)
        click.echo(f"{line.strip():<16} {session.state()}")


def _run_keys(session, step: float, heater_V: float, JogError) -> None:
    from tsa_bench.rig.jog import JogCommand

    click.echo(KEY_HELP)
    with _Keys() as keys:
        def pressed() -> bool:
            return keys.key(0) is not None

        while True:
            key = keys.key(0.1)
            session.idle()
            if key is None:
                continue
            cmd = {"+": JogCommand("move_by", step), "=": JogCommand("move_by", step),
                   "-": JogCommand("move_by", -step), "0": JogCommand("move_to", 0.0),
                   "q": JogCommand("quit"), " ": JogCommand("stop"),
                   "h": JogCommand("heater", 0.0 if session.heater_V > 0 else heater_V)}.get(key)
            if key in "[]":
                step = step / 2 if key == "[" else step * 2
                click.echo(f"step {step:g} turns")
                continue
            if key in "<>":
                cmd = JogCommand("rate", session.rate / 2 if key == "<" else session.rate * 2)
            if cmd is None:
                click.echo(KEY_HELP)
                continue
            try:
                if not session.execute(cmd, pressed):
                    return
            except JogError as exc:
                click.echo(f"refused: {exc}")
            click.echo(session.state())
