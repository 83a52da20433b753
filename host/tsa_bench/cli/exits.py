"""Exit codes shared by every command, and the one way a command reports bad input."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import NoReturn

import click

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_ABORTED = 0, 1, 2, 130


def fail(message: str, code: int = EXIT_BAD_INPUT) -> NoReturn:
    """Print ``error: <message>`` on stderr (one line per message line, never wrapped) and exit."""
    click.echo(f"error: {message}", err=True)
    sys.exit(code)


def unwritable_reason(path: str | os.PathLike[str]) -> str | None:
    """Why files cannot be written at ``path`` (a folder to be made or a file), or None if they can.

    Checked before long work starts, so a bad output path fails in a second, not after
    the analysis; it creates nothing (the nearest existing folder must be writable).
    """
    p = Path(path).absolute()
    probe = p
    while not probe.exists():
        if probe.parent == probe:
            return "no folder of it exists"
        probe = probe.parent
    if probe == p and not p.is_dir():
        return None if os.access(p, os.W_OK) else "the file is not writable"
    if not probe.is_dir():
        return f"{probe} is not a folder"
    if not os.access(probe, os.W_OK | os.X_OK):
        return f"{probe} is not writable"
    return None
