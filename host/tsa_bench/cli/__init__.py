"""Command line: the `tsa-bench` group, one module per family of commands.

- :mod:`.experiment`: validate, sim-serve, effects; :mod:`.run`: run (also --resume)
- :mod:`.data`: info, report, watch, export; :mod:`.importing`: import
- :mod:`.catalogue`: ls, catalogue (rebuild, check); :mod:`.lab`: lab; :mod:`.serve`: serve
- :mod:`.rig`: ports, check, jog; :mod:`.calibrate`: calibrate; :mod:`.zero`: zero
- :mod:`.models`: fit, predict, manipulator; :mod:`.estimate`: estimate
- :mod:`.diagnose`: diagnose
- :mod:`.reproduce`: reproduce
- :mod:`.sweep`: sweep

A command module parses options, calls the library and prints; it holds no logic of its
own and imports the library inside the command, so that ``--help`` and ``--version``
load click alone. Commands are looked up lazily by name (:class:`LazyGroup`).

Exit codes (all commands): 0 success; 1 the run or analysis failed, or the device could
not be reached; 2 bad input (nothing was sent to any device, nothing written);
130 aborted by the user.
"""

from __future__ import annotations

import importlib

import click

from tsa_bench import __version__

# command name -> "module:attribute" inside this package
COMMANDS: dict[str, str] = {
    "validate": "experiment:validate",
    "run": "run:run",
    "sim-serve": "experiment:sim_serve",
    "effects": "experiment:effects",
    "info": "data:info",
    "ls": "catalogue:ls_cmd",
    "catalogue": "catalogue:catalogue_cmd",
    "lab": "lab:lab",
    "serve": "serve:serve",
    "report": "data:report",
    "watch": "data:watch",
    "import": "importing:import_cmd",
    "export": "data:export",
    "fit": "models:fit_cmd",
    "predict": "models:predict_cmd",
    "manipulator": "models:manipulator_cmd",
    "diagnose": "diagnose:diagnose",
    "reproduce": "reproduce:reproduce",
    "sweep": "sweep:sweep",
    "ports": "rig:ports",
    "check": "rig:check",
    "jog": "rig:jog",
    "calibrate": "calibrate:calibrate",
    "zero": "zero:zero",
    "estimate": "estimate:estimate",
}


class LazyGroup(click.Group):
    """A click group whose commands are imported only when named (or listed by --help)."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        target = COMMANDS.get(cmd_name)
        if target is None:
            return None
        module, attr = target.split(":")
        return getattr(importlib.import_module(f"{__name__}.{module}"), attr)


@click.group(cls=LazyGroup)
@click.version_option(version=__version__, prog_name="tsa-bench")  # not importlib.metadata: no scan at start
def main() -> None:
    """tsa-bench: bench acquisition for twisted string actuators."""
