"""Opening user files safely: regular files only, bounded size, strict UTF-8.

Why: a FIFO given as an input blocks a reader forever, a device (``/dev/zero``) never
ends, and a huge file exhausts memory. :func:`read_text_file` opens without blocking,
checks with ``fstat`` on the open descriptor (no race with a swapped path) that it is a
regular file no larger than ``max_bytes``, and decodes strict UTF-8 (which also
refuses encoded lone surrogates). :func:`check_regular_file` does the same check for
readers that open the file themselves (HDF5). Symbolic links to regular files are
followed: a link is the user's own choice of name.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from tsa_bench.userfiles.errors import DocumentError, position_of

#: Default size limit for text documents a person writes (protocols, bench files, ...).
MAX_TEXT_BYTES = 4 * 1024 * 1024

_KINDS = {stat.S_IFIFO: "a FIFO (named pipe)", stat.S_IFCHR: "a character device", stat.S_IFBLK: "a block device",
          stat.S_IFSOCK: "a socket", stat.S_IFDIR: "a directory"}


def _kind(mode: int) -> str:
    return _KINDS.get(stat.S_IFMT(mode), "not a regular file")


def _open_error(name: str, what: str, exc: OSError) -> DocumentError:
    if exc.errno == errno.ENOENT:
        return DocumentError(name, None, None, f"{what} not found")
    if exc.errno == errno.EISDIR:
        return DocumentError(name, None, None, f"cannot read {what}: it is a directory")
    reason = exc.strerror or str(exc)
    return DocumentError(name, None, None, f"cannot read {what}: {reason}")


def check_regular_file(path: str | Path, what: str = "file") -> os.stat_result:
    """Raise DocumentError unless ``path`` names an existing regular file; return its stat."""
    name = str(path)
    try:
        st = os.stat(path)
    except OSError as exc:
        raise _open_error(name, what, exc) from None
    except ValueError as exc:  # e.g. an embedded NUL in the name
        raise DocumentError(name, None, None, f"cannot read {what}: {exc}") from None
    if not stat.S_ISREG(st.st_mode):
        raise DocumentError(name, None, None, f"cannot read {what}: it is {_kind(st.st_mode)}, not a regular file")
    return st


def read_bytes_file(path: str | Path, what: str = "file", max_bytes: int = MAX_TEXT_BYTES) -> bytes:
    """The bytes of a regular file of at most ``max_bytes``; DocumentError otherwise."""
    name = str(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
    except OSError as exc:
        raise _open_error(name, what, exc) from None
    except ValueError as exc:
        raise DocumentError(name, None, None, f"cannot read {what}: {exc}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise DocumentError(name, None, None,
                                f"cannot read {what}: it is {_kind(st.st_mode)}, not a regular file")
        if st.st_size > max_bytes:
            raise DocumentError(name, None, None, f"{what} is {st.st_size:,} bytes; at most {max_bytes:,} are read")
        chunks = []
        total = 0
        while True:
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                break
            total += len(chunk)
            if total > max_bytes:  # grew while we read it
                raise DocumentError(name, None, None, f"{what} is more than {max_bytes:,} bytes")
            chunks.append(chunk)
        return b"".join(chunks)
    except OSError as exc:
        raise _open_error(name, what, exc) from None
    finally:
        os.close(fd)


def decode_text(raw: bytes, name: str) -> str:
    """Strict UTF-8 (a leading BOM is dropped); DocumentError at the first bad byte."""
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        good = raw[: exc.start].decode("utf-8-sig", errors="replace")
        line, column = position_of(good, len(good))
        raise DocumentError(name, line, column, f"not UTF-8 text (bad byte 0x{raw[exc.start]:02X} "
                                                f"at byte offset {exc.start})") from None


def read_text_file(path: str | Path, what: str = "file", max_bytes: int = MAX_TEXT_BYTES) -> str:
    """A regular file's UTF-8 text (see the module docstring); DocumentError otherwise."""
    return decode_text(read_bytes_file(path, what, max_bytes), str(path))
