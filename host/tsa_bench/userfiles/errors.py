"""The error every document reader raises: one line naming file, position and problem."""

from __future__ import annotations


class DocumentError(ValueError):
    """A user file that cannot be read as the document it should be.

    ``str(err)`` is ``"FILE:LINE:COL: MESSAGE"`` (1-based line and column, as editors
    show them), or ``"FILE: MESSAGE"`` when there is no position (missing file, wrong
    kind of file). The message never contains a newline.
    """

    def __init__(self, file: str, line: int | None, column: int | None, message: str) -> None:
        self.file = file
        self.line = line
        self.column = column
        self.message = " ".join(message.split("\n"))
        super().__init__(str(self))

    @property
    def where(self) -> str:
        return self.file if self.line is None else f"{self.file}:{self.line}:{self.column or 1}"

    def __str__(self) -> str:
        return f"{self.where}: {self.message}"


def position_of(text: str, offset: int) -> tuple[int, int]:
    """1-based (line, column) of character ``offset`` in ``text``."""
    offset = max(0, min(offset, len(text)))
    line = text.count("\n", 0, offset) + 1
    column = offset - (text.rfind("\n", 0, offset) + 1) + 1
    return line, column
