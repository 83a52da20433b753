"""The operator channel between a rig's run and the lab supervisor: one socket, JSON lines.

Units: loads in g.

Contract: :class:`RigChannel` is the operator channel of one rig's ``tsa-bench run``
(``tell``, ``answer``, ``confirm``, ``ask``, as the terminal operator has them): each
call sends one line ``{"op": ..., "text": ..., "load_g": ..., "if_no": ...}`` to the
supervisor, and all but ``tell`` wait for its one-line reply: ``{"reply": TEXT}`` (the
person answered; for ``confirm`` "yes" or "no"), ``{"abort": true}`` (the person
pressed Ctrl-C: raises KeyboardInterrupt, as at the terminal) or ``{"absent": WHY}``
(nobody can answer: raises :class:`RigOperatorAbsent`). A closed socket is "absent"
too, so a run whose supervisor died asks nobody and ends as failed, never hangs. The
supervisor shows the text whole, naming the rig (:mod:`.supervisor`).
"""

from __future__ import annotations

import json
import socket
from typing import Any


class RigOperatorAbsent(RuntimeError):
    """Nobody can answer this rig's question: the message says why."""


def encode(message: dict[str, Any]) -> bytes:
    """One message as a JSON line."""
    return (json.dumps(message, ensure_ascii=False) + "\n").encode()


def decode(line: bytes) -> dict[str, Any] | None:
    """A JSON line as a message, or None for one that is not."""
    try:
        msg = json.loads(line.decode(errors="replace"))
    except ValueError:
        return None
    return msg if isinstance(msg, dict) else None


class RigChannel:
    """The rig side (module contract)."""

    def __init__(self, sock: socket.socket) -> None:
        self._sock = sock
        self._in = sock.makefile("rb")

    @classmethod
    def from_fd(cls, fd: int) -> "RigChannel":
        """The channel on an inherited socket descriptor (OSError if it is none)."""
        return cls(socket.socket(fileno=fd))

    def _send(self, message: dict[str, Any]) -> None:
        try:
            self._sock.sendall(encode(message))
        except OSError as exc:
            raise RigOperatorAbsent(f"nobody can answer: the lab supervisor is gone ({exc.strerror or exc})") from None

    def _ask(self, message: dict[str, Any]) -> str:
        self._send(message)
        line = self._in.readline()
        reply = decode(line) if line else None
        if reply is None:
            raise RigOperatorAbsent("nobody can answer: the lab supervisor is gone")
        if reply.get("abort"):
            raise KeyboardInterrupt
        if "absent" in reply:
            raise RigOperatorAbsent(str(reply["absent"]))
        return str(reply.get("reply", ""))

    def tell(self, text: str) -> None:
        try:
            self._send({"op": "tell", "text": text})
        except RigOperatorAbsent:
            pass   # a notice nobody reads changes nothing

    def answer(self, text: str, load_g: float | None) -> None:
        self._ask({"op": "answer", "text": text, "load_g": load_g})

    def confirm(self, question: str, *, if_no: str = "") -> bool:
        return self._ask({"op": "confirm", "text": question, "if_no": if_no}) == "yes"

    def ask(self, question: str) -> str:
        return self._ask({"op": "ask", "text": question})
