"""Hardened JSON for files the user hands us (saved models).

Contract of :func:`read_json` / :func:`parse_json`: a regular file of at most
``max_bytes`` (see :mod:`.files`), strict UTF-8, valid JSON (``NaN`` and
``Infinity`` allowed: models are saved with them), nested at most ``max_depth`` deep,
integers of at most ``max_int_digits`` digits, no lone surrogates in any text or
key. Anything else raises :class:`~tsa_bench.userfiles.errors.DocumentError` with
line and column where JSON gives them.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tsa_bench.userfiles.errors import DocumentError
from tsa_bench.userfiles.files import decode_text, read_bytes_file


@dataclass(frozen=True)
class JsonLimits:
    max_bytes: int = 64 * 1024 * 1024
    max_depth: int = 64
    max_int_digits: int = 40


def _depth_and_surrogates(value: Any, name: str, limits: JsonLimits) -> None:
    stack: list[tuple[Any, int]] = [(value, 1)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, (dict, list)):
            if d > limits.max_depth:
                raise DocumentError(name, None, None, f"nested more than {limits.max_depth} levels deep")
            items = list(v.items()) if isinstance(v, dict) else [(None, x) for x in v]
            for k, x in items:
                if isinstance(k, str):
                    _check_text(k, name)
                stack.append((x, d + 1))
        elif isinstance(v, str):
            _check_text(v, name)


def _check_text(text: str, name: str) -> None:
    for ch in text:
        if "\ud800" <= ch <= "\udfff":
            raise DocumentError(name, None, None, f"text holds a lone surrogate U+{ord(ch):04X} (not a character)")


def parse_json(text: str, name: str = "<string>", limits: JsonLimits = JsonLimits()) -> Any:
    """Parse and check JSON text; raise DocumentError (see the module contract)."""
    def parse_int(digits: str) -> int:
        if sum(ch.isdigit() for ch in digits) > limits.max_int_digits:
            raise ValueError(f"integer of {len(digits)} digits is too large (at most {limits.max_int_digits})")
        return int(digits)

    try:
        value = json.loads(text, parse_int=parse_int)
    except json.JSONDecodeError as exc:
        raise DocumentError(name, exc.lineno, exc.colno, f"not valid JSON: {exc.msg}") from None
    except RecursionError:
        raise DocumentError(name, None, None, f"nested more than {limits.max_depth} levels deep") from None
    except ValueError as exc:
        raise DocumentError(name, None, None, f"not valid JSON: {exc}") from None
    _depth_and_surrogates(value, name, limits)
    return value


def read_json(path: str | Path, *, what: str = "file", limits: JsonLimits = JsonLimits()) -> Any:
    """Read a regular file (bounded, strict UTF-8) and :func:`parse_json` it."""
    name = str(path)
    return parse_json(decode_text(read_bytes_file(path, what, limits.max_bytes), name), name, limits)
