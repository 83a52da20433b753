"""Protocol validation errors, each pinned to a file position and a dotted field path.

Contract: line and column numbers are 1-based (as editors show them); list indices in
field paths are 0-based (``steps[3]`` is the fourth step). ``line``/``column`` are
``None`` only when no position exists (e.g. the file could not be read).
"""

from __future__ import annotations

from collections.abc import Iterable

from yaml import Node
from yaml.error import Mark


class PlanError(Exception):
    """One problem in a protocol file.

    ``str(err)`` is ``"FILE:LINE:COL: FIELD: MESSAGE (allowed: ...)"``; the field part is
    left out for file-level problems and the allowed part when nothing sensible applies.
    """

    def __init__(
        self,
        file: str,
        line: int | None,
        column: int | None,
        field: str,
        message: str,
        allowed: str | None = None,
    ) -> None:
        self.file = file
        self.line = line
        self.column = column
        self.field = field
        self.message = message
        self.allowed = allowed
        super().__init__(self._render())

    def _render(self) -> str:
        where = self.file if self.line is None else f"{self.file}:{self.line}:{self.column or 1}"
        text = f"{where}: {self.field}: {self.message}" if self.field else f"{where}: {self.message}"
        return f"{text} (allowed: {self.allowed})" if self.allowed else text

    def __str__(self) -> str:
        return self._render()

    def __repr__(self) -> str:
        return f"PlanError({self._render()!r})"


class PlanErrors(Exception):
    """Every problem found in one protocol; ``str()`` lists them one per line, in file order."""

    def __init__(self, errors: Iterable[PlanError]) -> None:
        self.errors: list[PlanError] = list(errors)
        super().__init__(str(self))

    def __str__(self) -> str:
        return "\n".join(str(e) for e in self.errors)


class ErrorSink:
    """Collects :class:`PlanError` s for one file while a protocol is validated."""

    def __init__(self, filename: str) -> None:
        self.filename = filename
        self.errors: list[PlanError] = []

    def add(self, at: Node | Mark | None, field: str, message: str, allowed: str | None = None) -> None:
        """Record a problem at a node (its start), a YAML mark, or nowhere (``None``)."""
        mark = at.start_mark if isinstance(at, Node) else at
        line = None if mark is None else mark.line + 1
        column = None if mark is None else mark.column + 1
        self.errors.append(PlanError(self.filename, line, column, field, message, allowed))

    def __bool__(self) -> bool:
        return bool(self.errors)

    def __len__(self) -> int:
        return len(self.errors)

    def raise_if_any(self) -> None:
        """Raise :class:`PlanErrors` (sorted by position) when anything was recorded."""
        if self.errors:
            ordered = sorted(self.errors, key=lambda e: (e.line or 0, e.column or 0))
            raise PlanErrors(ordered)
