"""The memory budget for reading a file this tool did not write.

Why: a file's header can declare datasets far larger than the file (chunks never written
read as fill values): 31 MB declaring twenty-million-row columns, 1.9 KB declaring a
1 x 3e9 matrix. Reading such a file whole would take the machine's memory. So every reader
of a file from outside (run files, imported files) adds up what it is about to read
(rows x bytes per value, from the header alone) and calls :func:`check_budget` before
reading any data; over the budget it raises :class:`OverBudget`, whose message names the
file, what it would need, the budget, and ``--max-memory`` to raise it.

The budget: ``--max-memory SIZE`` of the command (:func:`set_memory_budget`), else the
environment variable ``TSA_BENCH_MAX_MEMORY``, else :data:`DEFAULT_BYTES` or half the
machine's memory, whichever is less.
"""

from __future__ import annotations

import os
import re

#: Default budget (bytes): a 5.5-hour 1 kHz run (20 million rows of the contract's columns,
#: about 1.4 GB) fits, with room for the copies an analysis makes.
DEFAULT_BYTES = 4 << 30
ENV = "TSA_BENCH_MAX_MEMORY"
_UNITS = {"": 1, "B": 1, "K": 1 << 10, "KB": 1 << 10, "KIB": 1 << 10, "M": 1 << 20, "MB": 1 << 20, "MIB": 1 << 20,
          "G": 1 << 30, "GB": 1 << 30, "GIB": 1 << 30, "T": 1 << 40, "TB": 1 << 40, "TIB": 1 << 40}

_budget: int | None = None


class OverBudget(ValueError):
    """Reading a file would take more memory than the budget; the message says how to raise it."""


def parse_size(text: str) -> int:
    """``"512M"``, ``"8G"``, ``"1.5GiB"``, ``"1000000"`` -> bytes; ValueError naming the text."""
    m = re.fullmatch(r"\s*([0-9]+(?:\.[0-9]*)?)\s*([A-Za-z]*)\s*", text)
    unit = m.group(2).upper() if m else None
    if not m or unit not in _UNITS:
        raise ValueError(f"{text!r} is not a size (give bytes or a number with K, M, G or T, e.g. 8G)")
    value = float(m.group(1)) * _UNITS[unit]
    if not 1 <= value <= 1 << 50:
        raise ValueError(f"{text!r}: a memory budget must be between 1 byte and 1 PiB")
    return int(value)


def _physical() -> int | None:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def memory_budget() -> int:
    """The budget now in force (bytes); see the module contract."""
    if _budget is not None:
        return _budget
    env = os.environ.get(ENV)
    if env:
        try:
            return parse_size(env)
        except ValueError:
            pass
    ram = _physical()
    return DEFAULT_BYTES if not ram else min(DEFAULT_BYTES, ram // 2)


def set_memory_budget(n_bytes: int | None) -> None:
    """Set the budget for this process (None: back to the default)."""
    global _budget
    _budget = n_bytes


def describe(n_bytes: float) -> str:
    """A size for people: ``"1.5 GiB"``, ``"512 MiB"``, ``"12 KiB"``."""
    for unit, size in (("TiB", 1 << 40), ("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n_bytes >= size:
            return f"{n_bytes / size:.3g} {unit}"
    return f"{int(n_bytes)} bytes"


def check_budget(needed: float, where: str, what: str) -> None:
    """OverBudget when reading ``what`` of ``where`` needs more than the budget (module contract)."""
    budget = memory_budget()
    if needed > budget:
        raise OverBudget(f"{where}: reading {what} would need {describe(needed)} of memory, more than the "
                         f"memory budget of {describe(budget)}; nothing was read (a file may declare more data than "
                         f"it holds). If the file is yours, raise the budget with --max-memory, e.g. "
                         f"--max-memory {max(1, int(needed * 1.25 / (1 << 30)) + 1)}G")
