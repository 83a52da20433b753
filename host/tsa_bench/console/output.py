"""Rich consoles that never hard-wrap text when the output is not a terminal.

Contract: :func:`make_console` returns a normal rich console on a terminal (colour,
the terminal's width, live displays). Anywhere else (a pipe, a file, a CI log, a
test) it returns a console without colour whose width is so large that no line is
ever broken or cropped, and that prints plain text with ``soft_wrap`` (one logical
line is one output line), so `grep` on a log finds every message whole and no test
depends on the terminal width or on the length of a path.
"""

from __future__ import annotations

import sys
from typing import TextIO

from rich.console import Console

#: Width given to consoles that are not terminals: wider than any line we print.
UNWRAPPED_WIDTH = 100_000


def make_console(*, stderr: bool = False, file: TextIO | None = None, terminal: bool | None = None,
                 markup: bool = True) -> Console:
    """A console on stdout (or stderr, or ``file``) that wraps only on a real terminal.

    ``terminal`` forces the decision (None: ask the stream whether it is a tty);
    ``markup=False`` prints strings exactly as given (no [tags], no highlighting).
    """
    stream = file if file is not None else (sys.stderr if stderr else sys.stdout)
    probe = Console(file=stream, force_terminal=terminal, markup=markup, highlight=markup)
    if probe.is_terminal:
        return probe
    return Console(file=stream, force_terminal=False, width=UNWRAPPED_WIDTH, soft_wrap=True,
                   color_system=None, highlight=False, emoji=False, markup=markup)
