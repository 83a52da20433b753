"""Write a file whole or not at all: a temporary beside it, renamed over it at the end.

Contract: ``with replacing(path) as tmp:`` yields ``tmp`` (``path`` plus ``suffix``) for the
caller to write; when the block ends without an exception ``tmp`` is renamed to ``path``
in one step (``os.replace``), so a reader never sees half a file. On any exit the
temporary is gone. Errors (``OSError`` and the caller's own) propagate unchanged.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def replacing(path: Path, suffix: str = ".writing") -> Iterator[Path]:
    """A temporary path beside ``path`` that becomes ``path`` on success (module contract)."""
    tmp = path.with_name(path.name + suffix)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
