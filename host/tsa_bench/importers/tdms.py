"""LabVIEW TDMS files through npTDMS (the optional extra ``tdms``).

Contract of :func:`read_tdms`: the channel group ``group`` (default the first with
channels) becomes the table, one column per channel of the group's most common length
(others left out, said so), named by channel, with the channel's ``unit_string`` as its
unit. Waveform channels (``wf_increment``) carry their own time, used for ``t`` when no
column is mapped to it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tsa_bench.importers.errors import SUPPORTED, ImportFileError
from tsa_bench.importers.table import Column, SourceTable
from tsa_bench.store.budget import OverBudget, check_budget


def read_tdms(path: Path, group: str | None) -> SourceTable:
    """Read one channel group (module contract) into a :class:`SourceTable`."""
    try:
        from nptdms import TdmsFile
    except ImportError:
        raise ImportFileError(f"{path}: a LabVIEW TDMS file; reading it needs the optional extra 'tdms' "
                              "(pip install 'tsa-bench[tdms]', which installs npTDMS)") from None
    try:
        meta = TdmsFile.read_metadata(path)   # channel lengths from the segment headers: no data read
        check_budget(sum(len(c) for g in meta.groups() for c in g.channels()) * 16.0, str(path), "its channels")
        f = TdmsFile.read(path)
        groups = f.groups()
    except (MemoryError, OverBudget):
        raise
    except Exception as exc:  # npTDMS raises ValueError, KeyError, struct.error ... on damaged files
        raise ImportFileError(f"{path}: looks like a LabVIEW TDMS file but cannot be read "
                              f"({type(exc).__name__}: {exc}); supported formats: {SUPPORTED}") from None
    names = [g.name for g in groups]
    if group is not None:
        if group not in names:
            raise ImportFileError(f"{path}: no channel group '{group}' (groups: {', '.join(names) or 'none'})")
        g = f[group]
    else:
        with_data = [g for g in groups if g.channels()]
        if not with_data:
            raise ImportFileError(f"{path}: looks like a LabVIEW TDMS file but cannot be read: no channel group "
                                  f"holds channels (empty or cut short); supported formats: {SUPPORTED}")
        g = with_data[0]
    chans = [c for c in g.channels() if np.asarray(c[:]).dtype.kind in "fiub"]
    if not chans:
        raise ImportFileError(f"{path}: group '{g.name}' has no numeric channels")
    lengths = [len(c) for c in chans]
    n = max(set(lengths), key=lengths.count)
    kept = [c for c in chans if len(c) == n]
    notes = [f"group '{g.name}'" + (f" of {len(names)} ({', '.join(names)}; --group)" if len(names) > 1 else "")]
    other = [c.name for c in chans if len(c) != n]
    if other:
        notes.append(f"channels of another length left out: {', '.join(other)}")
    cols = [Column(c.name, np.asarray(c[:], float), unit=str(c.properties.get("unit_string", "") or ""))
            for c in kept]
    time_s = None
    wf = next((c for c in kept if "wf_increment" in c.properties), None)
    if wf is not None:
        time_s = np.asarray(wf.time_track(), float)
        notes.append(f"waveform timing of '{wf.name}': every {float(wf.properties['wf_increment']):g} s")
    return SourceTable(path, "TDMS", cols, np.arange(1, n + 1), None, True, notes, time_s=time_s, row_prefix="row ")
