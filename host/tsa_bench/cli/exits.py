"""Exit codes shared by every command, and the one way a command reports bad input."""

from __future__ import annotations

import sys
from typing import NoReturn

import click

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_ABORTED = 0, 1, 2, 130


def fail(message: str, code: int = EXIT_BAD_INPUT) -> NoReturn:
    """Print ``error: <message>`` on stderr (one line per message line, never wrapped) and exit."""
    click.echo(f"error: {message}", err=True)
    sys.exit(code)
