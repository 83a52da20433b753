"""Links between the files of one experiment: a resumed run and the run it continues.

Contract: the resumed file names the first in its root attributes ``resumed_from``
(file name), ``resumed_from_path`` (absolute path), ``resumed_from_created`` (the
first file's ``created``) and ``first_segment``; :func:`link_continuation` adds
``continued_in`` (the resumed file's name) to the first file once the resumed run has
written its file - an attribute only, no recorded data is changed.
"""

from __future__ import annotations

from pathlib import Path

import h5py


def link_continuation(first: str | Path, resumed: str | Path) -> str | None:
    """Write ``continued_in`` into ``first``; returns a warning text when it cannot."""
    try:
        with h5py.File(first, "a") as f:
            names = [n for n in str(f.attrs.get("continued_in", "")).split(";") if n]
            name = Path(resumed).name if Path(resumed).resolve().parent == Path(first).resolve().parent \
                else str(Path(resumed).resolve())
            if name not in names:
                names.append(name)
            f.attrs["continued_in"] = ";".join(names)
    except (OSError, RuntimeError) as exc:
        return f"could not note the continuation in {first} ({exc}); {resumed} still names it"
    return None
