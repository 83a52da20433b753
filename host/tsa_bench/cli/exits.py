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


def check_output(path: str | os.PathLike[str] | None, force: bool) -> None:
    """Exit 2 before any work when the output file ``path`` exists (as a file or a link)
    and ``--force`` was not given; a folder is never replaced."""
    if path is None:
        return
    p = Path(path)
    if os.path.lexists(p) and (not force or (p.is_dir() and not p.is_symlink())):
        what = "a symbolic link" if p.is_symlink() else ("a folder" if p.is_dir() else "a file")
        fail(f"{p} already exists ({what}); " + ("choose another name" if p.is_dir() and not p.is_symlink()
                                                 else "give --force to replace it, or choose another name")
             + "; nothing was written")


def check_output_folder(folder: str | os.PathLike[str] | None, force: bool) -> None:
    """Exit 2 before any work when the output folder holds files already (an earlier
    report) and ``--force`` was not given, or is a link (never written through)."""
    if folder is None:
        return
    p = Path(folder)
    if p.is_symlink():
        fail(f"{p} is a symbolic link; give a real folder (outputs are never written through a link); "
             "nothing was written")
    if p.is_dir() and not force and any(p.iterdir()):
        fail(f"{p} already holds files; give --force to replace the ones this command writes, or --out another "
             "folder; nothing was written")
