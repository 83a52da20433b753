"""Parse the ``track_length`` step: closed-loop length control from resistance alone.

Units: lengths in mm, times in s, twist in turns, rates in turns/s, accelerations in turns/s^2.

Keys (each step is ``{track_length: {...}}``):

====================  =====================================================================
model                 a self-sensing model JSON written by ``tsa-bench fit self-sensing``
                      (resistance only), or a load-strain model from ``tsa-bench estimate
                      --train`` (resistance and twist); path relative to the protocol file
length_mm, hold_s     one target and how long to keep it once reached, or
targets               a list of ``{length_mm, hold_s}``
tolerance_mm          error at which a target counts as reached (default 0.1)
gain                  fraction of the estimated error corrected per move (0 < gain <= 1.5, default 0.8)
initial_mm_per_turn   first guess of dL/dturn (default -0.8; updated from the estimates)
settle_s              wait after each stop before the estimate is judged (default 5)
window_s              estimate averaged over at most this much of a hold (default 10)
max_step_turns        largest single correction (default 10)
rate_turns_per_s,     motion of the corrections (default: the protocol defaults)
accel_turns_per_s2
timeout_s             per target: not reached within this -> ``on_timeout`` (default 180)
on_timeout            ``continue`` (record it, next target; default) or ``fail`` (end the run)
====================  =====================================================================

The model is read and checked here, so ``validate`` refuses a file that is not a
self-sensing model, has no validity range, or a target outside that range, with the
position of the offending key, before anything moves.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from yaml import MappingNode, Node

from tsa_bench.plan.actions import TrackLength
from tsa_bench.plan.yamlnodes import describe

if TYPE_CHECKING:
    from tsa_bench.plan.ops import Op, StepParsing

KEYS = ("model", "length_mm", "hold_s", "targets", "tolerance_mm", "gain", "initial_mm_per_turn", "settle_s",
        "window_s", "max_step_turns", "rate_turns_per_s", "accel_turns_per_s2", "timeout_s", "on_timeout")
MAX_TARGETS = 10_000
MAX_S = 7 * 24 * 3600.0


def model_info(path: Path) -> tuple[tuple[float, float], str | None]:
    """(validity range in mm, training bench name) of a self-sensing model file; raises
    ModelFileError with the reason when it cannot be used for control."""
    from tsa_bench.models import load_strain
    from tsa_bench.models.saved import ModelFileError, load_model_file

    if _format(path) == load_strain.FORMAT:   # resistance and twist (load-robust)
        try:
            ls = load_strain.load(path)
        except load_strain.LoadStrainError as exc:
            raise ModelFileError(str(exc)) from None
        return ls.length_range_mm(), ls.bench
    saved = load_model_file(path)
    if saved.model != "self-sensing":
        raise ModelFileError(f"{path}: is a '{saved.model}' model; track_length needs a 'self-sensing' model "
                             "(resistance -> length, from `tsa-bench fit self-sensing`)")
    rng = saved.options.get("length_range_mm")
    if not (isinstance(rng, list) and len(rng) == 2 and all(isinstance(v, (int, float)) for v in rng)
            and rng[0] < rng[1]):
        raise ModelFileError(f"{path}: has no validity range (options.length_range_mm); refit it with "
                             "`tsa-bench fit self-sensing`, which records the lengths it was identified on")
    bench = saved.options.get("bench")
    from tsa_bench.models.fitting import from_saved

    from_saved(saved)  # every parameter present
    return (float(rng[0]), float(rng[1])), bench if isinstance(bench, str) else None


def _format(path: Path) -> str | None:
    """The ``format`` of a JSON model file (None when it cannot be read; the loader then says why)."""
    from tsa_bench.userfiles import DocumentError, read_json

    try:
        doc = read_json(path, what="model file")
    except DocumentError:
        return None
    return doc.get("format") if isinstance(doc, dict) else None


def parse_track_length(parser: StepParsing, node: Node, field: str, source: str) -> list[Op] | None:
    """The ``track_length`` step as one action (None after reporting errors)."""
    from tsa_bench.models.saved import ModelFileError
    from tsa_bench.plan.ops import ActionOp

    r = parser.reader
    fields = r.mapping(node, field, KEYS, required=("model",))
    if fields is None:
        return None
    ok = True

    def num(key: str, unit: str, default: float, **bounds) -> float:
        nonlocal ok
        if key not in fields:
            return default
        v = r.number(fields[key], f"{field}.{key}", unit, **bounds)
        if v is None:
            ok = False
            return default
        return v

    tolerance = num("tolerance_mm", "mm", 0.1, gt=0, le=10.0)
    gain = num("gain", "1", 0.8, gt=0, le=1.5)
    slope = num("initial_mm_per_turn", "mm/turn", -0.8)
    if "initial_mm_per_turn" in fields and slope == 0:
        r.sink.add(fields["initial_mm_per_turn"], f"{field}.initial_mm_per_turn", "must not be 0", "a slope != 0")
        ok = False
    settle = num("settle_s", "s", 5.0, gt=0, le=600.0)
    window = num("window_s", "s", 10.0, gt=0, le=MAX_S)
    max_step = num("max_step_turns", "turns", 10.0, gt=0)
    timeout = num("timeout_s", "s", 180.0, gt=0, le=MAX_S, le_name="7 days")
    motion = parser._motion(fields, node, field)
    if motion is None:
        ok = False
    on_timeout = "continue"
    if "on_timeout" in fields:
        on_timeout = r.string(fields["on_timeout"], f"{field}.on_timeout") or ""
        if on_timeout not in ("continue", "fail"):
            r.sink.add(fields["on_timeout"], f"{field}.on_timeout", f"unknown choice {on_timeout!r}",
                       "continue, fail")
            ok = False

    targets = _targets(parser, fields, node, field)
    if targets is None:
        ok = False
    valid, bench, model_path = None, None, ""
    if "model" in fields:
        text = r.string(fields["model"], f"{field}.model")
        if text is None:
            return None
        p = Path(text)
        if not p.is_absolute():
            p = parser.folder / p
        model_path = str(p.resolve())
        try:
            valid, bench = model_info(p)
        except ModelFileError as exc:
            r.sink.add(fields["model"], f"{field}.model", str(exc))
            return None
    if not ok or targets is None or valid is None:
        return None
    lo, hi = valid
    for (length, _), tnode, tfield in targets:
        if not lo <= length <= hi:
            r.sink.add(tnode, tfield, f"target {length:g} mm is outside the model's validity range "
                                      f"{lo:g}..{hi:g} mm (the lengths it was identified on)",
                       f"{lo:g}..{hi:g} mm")
            ok = False
    if not ok:
        return None
    rate, accel = motion  # type: ignore[misc]
    return [ActionOp(TrackLength(model_path, tuple(t for t, _, _ in targets), tolerance, gain, slope, settle, window,
                                 max_step, rate, accel, timeout, on_timeout, valid, bench), source)]


def _targets(parser: StepParsing, fields: dict[str, Node], node: Node, field: str
             ) -> list[tuple[tuple[float, float], Node, str]] | None:
    """[((length_mm, hold_s), node of the length, its field)], or None after an error."""
    r = parser.reader
    if ("targets" in fields) == ("length_mm" in fields):
        r.sink.add(node, field, "give either length_mm (with hold_s) or targets", "length_mm + hold_s, or targets")
        return None
    if "length_mm" in fields:
        length = r.number(fields["length_mm"], f"{field}.length_mm", "mm", gt=0)
        hold = r.number(fields["hold_s"], f"{field}.hold_s", "s", ge=0, le=MAX_S, le_name="7 days") \
            if "hold_s" in fields else 0.0
        if length is None or hold is None:
            return None
        return [((length, hold), fields["length_mm"], f"{field}.length_mm")]
    if "hold_s" in fields:
        r.sink.add(fields["hold_s"], f"{field}.hold_s", "hold_s goes inside each of targets", "targets: [{length_mm, hold_s}]")
        return None
    items = r.sequence(fields["targets"], f"{field}.targets", "targets")
    if items is None:
        return None
    if len(items) > MAX_TARGETS:
        r.sink.add(fields["targets"], f"{field}.targets", f"{len(items):,} targets", f"at most {MAX_TARGETS:,}")
        return None
    out = []
    for j, item in enumerate(items):
        f = f"{field}.targets[{j}]"
        if not isinstance(item, MappingNode):
            r.sink.add(item, f, f"expected {{length_mm, hold_s}}, got {describe(item)}", "length_mm, hold_s")
            return None
        sub = r.mapping(item, f, ("length_mm", "hold_s"), required=("length_mm",))
        if sub is None or "length_mm" not in sub:
            return None
        length = r.number(sub["length_mm"], f"{f}.length_mm", "mm", gt=0)
        hold = r.number(sub["hold_s"], f"{f}.hold_s", "s", ge=0, le=MAX_S, le_name="7 days") \
            if "hold_s" in sub else 0.0
        if length is None or hold is None:
            return None
        out.append(((length, hold), sub["length_mm"], f"{f}.length_mm"))
    return out
