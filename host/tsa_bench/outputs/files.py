"""Writing output files safely: created exclusively, never through a planted link, whole or not at all.

Why: on a shared lab drive anyone who can write a folder can plant a symbolic link where
a command is about to write (a link named ``OUT.h5.writing`` would make the command write
into the link's target), and two commands started at once can pick the same file name.
So every file a command writes is

* created with ``O_CREAT | O_EXCL | O_NOFOLLOW`` (:func:`create_new`, :func:`reserve_free_name`):
  creation fails instead of following a link or reusing a file, and of two processes
  asking for the same name exactly one gets it (the other takes the next free name);
* written under a random temporary name in the target folder (:func:`temp_name`), then
  published in one step (:func:`publish`): ``link(tmp, path)``, which fails when ``path``
  exists (as a file or as a link), or, with ``force``, ``rename(tmp, path)``, which
  replaces a file or a link without ever following it. A reader never sees half a file;
  a failure leaves no temporary behind (:func:`writing`).

Contract of :func:`writing`: ``with writing(path, force) as tmp:`` refuses at once with
:class:`OutputExists` when ``path`` exists and ``force`` is false; yields a fresh path in the
same folder that does not exist yet (the caller creates it exclusively: ``open_new(tmp)``
or h5py mode ``"x"``); when the block ends without an exception, publishes it as ``path``
(refusing then too if ``path`` appeared meanwhile). On any exit the temporary is gone.

Derived outputs (a model, a report, figures, CSV, JSON) are written through
:func:`write_text`, :func:`open_output` and :func:`save_figure`, which do the above; their
``force`` defaults to what the command allows (:func:`replace_allowed`, set by a command's
``--force``): an existing file is refused unless the user asked to replace it.
"""

from __future__ import annotations

import contextvars
import errno
import io
import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, BinaryIO

_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_replace_allowed: contextvars.ContextVar[bool] = contextvars.ContextVar("tsa_bench_replace_allowed", default=False)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)
#: errno values of a file system without hard links (FAT, some network shares)
_NO_LINKS = {errno.EPERM, errno.EOPNOTSUPP, errno.ENOTSUP, errno.EMLINK, errno.EXDEV}


class OutputExists(FileExistsError):
    """The output file exists and may not be replaced; the message says what to do."""

    def __init__(self, path: Path, hint: str = "give --force to replace it") -> None:
        kind = "a symbolic link" if path.is_symlink() else ("a folder" if path.is_dir() else "a file")
        super().__init__(errno.EEXIST, f"{path} already exists ({kind}); {hint} (nothing was written)", str(path))
        self.path = path

    def __str__(self) -> str:
        return str(self.strerror)


def create_new(path: str | Path, mode: int = 0o644) -> int:
    """Create ``path`` exclusively (never through a link) and return its open descriptor
    (write-only). FileExistsError when anything, a dangling link included, is there."""
    return os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW | _CLOEXEC, mode)


def open_new(path: str | Path) -> BinaryIO:
    """:func:`create_new` as a binary file object."""
    return os.fdopen(create_new(path), "wb")


def reserve_free_name(folder: str | Path, stem: str, suffix: str = ".h5") -> Path:
    """Create and return the first free one of ``stem.h5``, ``stem-2.h5``, ``stem-3.h5``, ...
    in ``folder`` (an empty file, created exclusively: concurrent callers get different names)."""
    folder = Path(folder)
    n = 1
    while True:
        path = folder / (f"{stem}{suffix}" if n == 1 else f"{stem}-{n}{suffix}")
        try:
            os.close(create_new(path))
            return path
        except FileExistsError:
            n += 1
            if n > 100_000:
                raise


def temp_name(path: str | Path, tag: str = "writing") -> Path:
    """A random name beside ``path`` (``NAME.<random>.<tag>``) that does not exist now."""
    p = Path(path)
    while True:
        tmp = p.with_name(f"{p.name}.{secrets.token_hex(6)}.{tag}")
        if not os.path.lexists(tmp):
            return tmp


def refuse_existing(path: str | Path, force: bool = False, hint: str = "give --force to replace it") -> None:
    """OutputExists when ``path`` exists (or is a link) and ``force`` is false; a folder is
    never replaced."""
    p = Path(path)
    if os.path.lexists(p) and (not force or (p.is_dir() and not p.is_symlink())):
        raise OutputExists(p, hint if not p.is_dir() else "choose a file name")


def publish(tmp: Path, path: Path, force: bool = False) -> None:
    """Make the finished ``tmp`` appear as ``path`` in one step (module contract) and remove
    the name ``tmp``. Without ``force`` an existing ``path`` (file or link) is refused."""
    if force:
        refuse_existing(path, True)
        os.replace(tmp, path)
        return
    try:
        os.link(tmp, path, follow_symlinks=False)
    except FileExistsError:
        raise OutputExists(path) from None
    except OSError as exc:
        if exc.errno not in _NO_LINKS:
            raise
        refuse_existing(path)        # no hard links here: the narrow check-then-rename instead
        os.rename(tmp, path)
        return
    os.unlink(tmp)


@contextmanager
def writing(path: str | Path, force: bool | None = None, tag: str = "writing",
            hint: str = "give --force to replace it") -> Iterator[Path]:
    """A temporary path beside ``path`` that becomes ``path`` on success (module contract);
    ``force`` None: as the command allows (:func:`replace_allowed`)."""
    p = Path(path)
    force = _force(force)
    refuse_existing(p, force, hint)
    tmp = temp_name(p, tag)
    try:
        yield tmp
        try:
            publish(tmp, p, force)
        except OutputExists:
            raise OutputExists(p, hint) from None
    finally:
        try:
            if os.path.lexists(tmp):
                os.unlink(tmp)
        except OSError:
            pass


def same_file(fd: int, path: str | Path) -> bool:
    """Whether ``path`` (not followed) is the regular file open as ``fd``: a check that a
    library which opens by name (HDF5) opened the file this process created."""
    try:
        a, b = os.fstat(fd), os.lstat(path)
    except OSError:
        return False
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


@contextmanager
def replace_allowed(allowed: bool = True) -> Iterator[None]:
    """Within the block, derived outputs may replace existing files (a command's ``--force``)."""
    token = _replace_allowed.set(allowed)
    try:
        yield
    finally:
        _replace_allowed.reset(token)


def allow_replace() -> bool:
    """Whether derived outputs may replace existing files now (:func:`replace_allowed`)."""
    return _replace_allowed.get()


def _force(force: bool | None) -> bool:
    return _replace_allowed.get() if force is None else force


@contextmanager
def open_output(path: str | Path, mode: str = "w", force: bool | None = None, **kw: Any) -> Iterator[IO]:
    """A file object writing ``path`` whole or not at all (module contract); ``mode`` "w" (text,
    UTF-8 unless ``encoding`` is given) or "wb"."""
    if mode not in ("w", "wb"):
        raise ValueError(f"open_output writes new files: mode 'w' or 'wb', not {mode!r}")
    p = Path(path)
    with writing(p, force) as tmp:
        raw = open_new(tmp)
        f: IO = raw if mode == "wb" else io.TextIOWrapper(raw, encoding=kw.pop("encoding", "utf-8"), **kw)
        with f:
            yield f
            f.flush()
            os.fsync(f.fileno())   # whole on disk before it gets its name (a full disk fails here, not later)


def write_text(path: str | Path, text: str, force: bool | None = None, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` (module contract); returns the path."""
    with open_output(path, "w", force, encoding=encoding) as f:
        f.write(text)
    return Path(path)


def save_figure(fig: Any, path: str | Path, force: bool | None = None, **kw: Any) -> Path:
    """A matplotlib figure saved to ``path`` in the format of its suffix (module contract)."""
    p = Path(path)
    kw.setdefault("format", p.suffix.lstrip(".").lower() or "png")
    with open_output(p, "wb", force) as f:
        fig.savefig(f, **kw)
    return p
