"""Where a value in a Bluesky document came from: ``tsa-bench:<port or file>#<quantity>``.

Contract: every data key the rig, the protocol flyer and the run-file export write has
such a ``source``; the quantity after ``#`` names the run-file column (``t``,
``turns``, ``length``, ``resistance``, ``heater_voltage``, ``load``, ...), a rig
reading (``device_time``, ``sampling_period``, ...), a segment or event field
(``segment_index``, ``event_kind``, ...) or a configuration text (``protocol``,
``bench``). The documents bridge knows columns by it, never by key names. No bluesky
or ophyd-async import here (the export uses it with event-model alone).
"""

from __future__ import annotations

PREFIX = "tsa-bench:"


def source_of(where: str, quantity: str) -> str:
    """``tsa-bench:<where>#<quantity>``."""
    return f"{PREFIX}{where}#{quantity}"


def quantity_of(source: str) -> str | None:
    """The quantity of a tsa-bench source; None for any other source."""
    if not source.startswith(PREFIX) or "#" not in source:
        return None
    return source.rsplit("#", 1)[1] or None
