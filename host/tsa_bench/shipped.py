"""The configuration files shipped with tsa-bench: bench presets, protocols, thesis data.

In the source tree they live in ``configs/`` at the repository root; a built wheel
carries a copy of the whole folder as package data (``tsa_bench/_configs/``, copied by
``setup.py``), so an installed tsa-bench finds them without the source tree.

Search path (contract, documented in README.md): a protocol or bench path given on the
command line is used as is when it exists. Otherwise a relative path is looked up in
the shipped configs, in this order: the path itself below the configs root with a
leading ``configs/`` removed (``configs/protocols/lifetime.yaml`` and
``protocols/lifetime.yaml``), then the file name in the folder of its kind
(``protocols/`` or ``bench/``), with ``.yaml`` added when it has no suffix
(``lifetime``). Nothing else is searched; an absolute path is never replaced.
"""

from __future__ import annotations

from pathlib import Path, PurePosixPath

_PACKAGE_COPY = Path(__file__).resolve().parent / "_configs"
_SOURCE_TREE = Path(__file__).resolve().parents[2] / "configs"


def configs_root() -> Path:
    """The folder holding the shipped configs (the wheel's copy, else the source tree's)."""
    if _PACKAGE_COPY.is_dir():
        return _PACKAGE_COPY
    return _SOURCE_TREE


def shipped(relative: str) -> Path:
    """``configs/<relative>`` of this installation (it may not exist)."""
    return configs_root() / relative


def find_config(path: str | Path, kind: str) -> tuple[Path, bool]:
    """Where the file named ``path`` is: ``(path, False)`` when it exists as given (or
    cannot be found anywhere), ``(shipped copy, True)`` when the search path found it.

    ``kind`` is the shipped folder for bare names: ``"protocols"`` or ``"bench"``.
    """
    given = Path(path)
    if given.exists() or given.is_absolute() or not str(path).strip():
        return given, False
    root = configs_root()
    parts = PurePosixPath(given.as_posix()).parts
    if parts and parts[0] == "configs":
        parts = parts[1:]
    candidates = []
    if parts and ".." not in parts:
        candidates.append(root.joinpath(*parts))
    name = given.name
    candidates.append(root / kind / name)
    if not given.suffix:
        candidates.append(root / kind / f"{name}.yaml")
    for candidate in candidates:
        if candidate.is_file():
            return candidate, True
    return given, False
