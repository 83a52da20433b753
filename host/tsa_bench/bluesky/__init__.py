"""The rig from Bluesky: an ophyd-async device, a protocol flyer, and a documents bridge.

An optional extra (``pip install "tsa-bench[bluesky]"``): nothing else in tsa_bench
imports this room, and the names below are imported on first use (PEP 562), so
``import tsa_bench.bluesky`` needs neither bluesky nor ophyd-async until one is used.

* :class:`TsaRig` (:mod:`.device`): twist and heater to move, length, resistance,
  step position and device time to read, load declared as configuration.
* :class:`ProtocolFlyer` (:mod:`.flyer`): a YAML protocol run on the rig by the
  project's runner as one step of a plan, its samples collected as events;
  :func:`run_protocol` (:mod:`.plans`) the plan that streams them while it runs.
* :class:`RunFileWriter` (:mod:`.bridge`): a RunEngine callback writing each run as a
  tsa-bench run file; :func:`run_documents` (:mod:`.export`) the reverse.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

#: public name -> the submodule that defines it
_WHERE = {
    "TsaRig": "device", "TwistAxis": "device", "HeaterAxis": "device",
    "Acquisition": "session", "PositionUnknown": "session", "RigFault": "session", "RigRefused": "session",
    "RigStopped": "session",
    "ProtocolFlyer": "flyer", "run_protocol": "plans",
    "RunFileWriter": "bridge", "run_documents": "export",
}

__all__ = list(_WHERE)

if TYPE_CHECKING:
    from tsa_bench.bluesky.bridge import RunFileWriter
    from tsa_bench.bluesky.device import HeaterAxis, TsaRig, TwistAxis
    from tsa_bench.bluesky.export import run_documents
    from tsa_bench.bluesky.flyer import ProtocolFlyer
    from tsa_bench.bluesky.plans import run_protocol
    from tsa_bench.bluesky.session import Acquisition, PositionUnknown, RigFault, RigRefused, RigStopped


def __getattr__(name: str) -> Any:
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module 'tsa_bench.bluesky' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"tsa_bench.bluesky.{where}"), name)
    globals()[name] = value
    return value
