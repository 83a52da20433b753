"""Bluesky documents -> a tsa-bench run file: ``RE.subscribe(RunFileWriter("runs", rig=rig))``.

Units: the run file's (docs/run-format.md): t s, turns turn, length mm, resistance ohm,
heater_voltage V, load N (a rig's ``load`` signal, in g, is converted).

Contract of :class:`RunFileWriter`, a RunEngine callback ``(name, doc)``: each Bluesky
run that records tsa-bench data becomes one run file, written by the project's
:class:`~tsa_bench.store.RunWriter` (the same writer as ``tsa-bench run``, crash-safe,
flushed as it goes), so ``info``, ``report``, ``fit`` and ``diagnose`` read it.

* The file is made at the run's first descriptor of a stream holding tsa-bench data
  (sources ``tsa-bench:<port>#<quantity>``): in ``out`` when it is a folder
  (``<start time>_<plan>_<uid>.h5``), or ``out`` itself when it ends in ``.h5`` (one run;
  an existing file is never overwritten: :class:`FileExistsError` before anything is written).
* Samples: the rows of one stream, the first such stream with a sample quantity (a
  protocol flyer's samples, else the plan's ``primary`` readings); the other streams'
  readings are not rows (an event says which were left out). Each row takes the columns
  its event holds (by quantity); when ``rig`` is given, what an event does not hold comes
  from the rig's acquisition it was read from (found by the reading's timestamp), so
  ``count([rig.length])`` still stores twist, resistance, heater, load and device time.
  ``t``: a flyer's own protocol time; else the rig's device time of the acquisition, from
  the run's first row; else the event's wall time since the run started. Missing
  quantities are NaN (``turns``, ``length``, ``resistance``, ``heater_voltage``,
  ``load``), ``segment`` -1 (a point has no protocol step), ``motor_moving`` 0 (readings
  are taken at rest), ``counter`` the event's sequence number. Other numeric scalar keys
  (another device's) are stored as extra columns with their units.
* A flyer's ``<name>_segments`` and ``<name>_events`` streams become ``/segments`` and
  ``/events``; its configuration gives ``/config/protocol`` and ``/config/bench``.
  Without a flyer, ``/config/protocol`` describes the Bluesky plan (as YAML comments)
  and ``/config/bench`` is the rig's bench file (empty without ``rig``).
* ``exit_status``: Bluesky's "success", "abort", "fail" -> "success", "aborted",
  "failed", with the stop document's reason. ``backend``: the rig's ("sim" or
  "serial"), else "import" (another tool wrote it).
"""

from __future__ import annotations

import datetime as dt
import json
import logging
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from tsa_bench.bluesky.sources import quantity_of
from tsa_bench.protocol import msg
from tsa_bench.rundocs import SAMPLE_COLUMNS, EventRecord, RunStart, RunStop, SampleBlock, SegmentRecord
from tsa_bench.store import RunWriter
from tsa_bench.units import G_N_PER_G

log = logging.getLogger(__name__)

#: Quantities that make a stream's rows samples.
SAMPLE_QUANTITIES = frozenset({"t", "device_time", "turns", "length", "resistance", "heater_voltage"})
EXIT_STATUS = {"success": "success", "abort": "aborted", "fail": "failed"}


def _columns(rows: list[dict[str, float]]) -> dict[str, np.ndarray]:
    return {k: np.array([r[k] for r in rows], dtype=d) for k, (d, _) in SAMPLE_COLUMNS.items()}


class _Run:
    """What one Bluesky run has given so far."""

    def __init__(self, start: dict) -> None:
        self.start = start
        self.writer: RunWriter | None = None
        self.path: Path | None = None
        self.sample_stream: str | None = None
        self.descriptors: dict[str, dict] = {}           # uid -> descriptor
        self.roles: dict[str, str] = {}                  # descriptor uid -> samples | segments | events | other
        self.extra: dict[str, tuple[str, str, dict[str, str]]] = {}   # extra column -> (dtype, units, attrs)
        self.t0: float | None = None
        self.t_last = -math.inf
        self.rows = 0
        self.left_out: set[str] = set()


class RunFileWriter:
    """A RunEngine callback writing each run as a run file (see the module contract).

    ``out``: a folder (one file per run) or a ``.h5`` path (one run); ``rig``: the
    :class:`~tsa_bench.bluesky.TsaRig` the plans read (optional). :attr:`paths` lists
    the files written, in order."""

    def __init__(self, out: str | Path, *, rig: Any = None) -> None:
        self.out = Path(out)
        self.rig = rig
        self.paths: list[Path] = []
        self._runs: dict[str, _Run] = {}
        self._desc_run: dict[str, str] = {}

    def __call__(self, name: str, doc: dict) -> None:
        handler = getattr(self, f"_on_{name}", None)
        if handler is not None:
            handler(doc)

    # -- documents -----------------------------------------------------------------
    def _on_start(self, doc: dict) -> None:
        self._runs[doc["uid"]] = _Run(doc)

    def _on_descriptor(self, doc: dict) -> None:
        run = self._runs.get(doc["run_start"])
        if run is None:
            return
        self._desc_run[doc["uid"]] = doc["run_start"]
        run.descriptors[doc["uid"]] = doc
        quantities = {quantity_of(k.get("source", "")) for k in doc["data_keys"].values()}
        stream = doc.get("name", "primary")
        if quantities & SAMPLE_QUANTITIES:
            if run.sample_stream is None:
                run.sample_stream = stream
            role = "samples" if run.sample_stream == stream else "other"
        elif any(q and q.startswith("segment_") for q in quantities):
            role = "segments"
        elif any(q and q.startswith("event_") for q in quantities):
            role = "events"
        else:
            role = "other"
        run.roles[doc["uid"]] = role
        if role == "other":
            run.left_out.add(stream)
            return
        if role == "samples":
            for key, dk in doc["data_keys"].items():
                if quantity_of(dk.get("source", "")) is None and dk.get("dtype") in ("number", "integer") \
                        and not dk.get("shape"):
                    run.extra[_column_name(key)] = ("f8", dk.get("units") or "1", {"bluesky_key": key})
        if run.writer is None:
            self._open(run, doc)

    def _on_event(self, doc: dict) -> None:
        self._rows(doc["descriptor"], [doc["data"]], [doc["timestamps"]], [doc["time"]], [doc["seq_num"]])

    def _on_event_page(self, doc: dict) -> None:
        n = len(doc["seq_num"])
        data = [{k: v[i] for k, v in doc["data"].items()} for i in range(n)]
        stamps = [{k: v[i] for k, v in doc["timestamps"].items()} for i in range(n)]
        self._rows(doc["descriptor"], data, stamps, list(doc["time"]), list(doc["seq_num"]))

    def _on_stop(self, doc: dict) -> None:
        run = self._runs.pop(doc["run_start"], None)
        if run is None:
            return
        if run.writer is None:
            log.warning("Bluesky run %s recorded no tsa-bench data: no run file written", doc["run_start"])
            return
        t_end = self._t_now(run, doc["time"])
        if run.left_out:
            run.writer.on_event(EventRecord(t_end, "bluesky_streams_left_out",
                                            "streams not stored as samples: " + ", ".join(sorted(run.left_out))))
        status = EXIT_STATUS.get(doc.get("exit_status", ""), "failed")
        reason = doc.get("reason") or ("the Bluesky run ended" if status == "success" else
                                       f"the Bluesky run ended '{doc.get('exit_status', '?')}' (RunEngine abort, "
                                       "stop or a failed plan)")
        run.writer.on_stop(RunStop(status, reason, t_end, run.rows, 0, 0, doc["time"] - run.start["time"]))

    # -- the file ---------------------------------------------------------------------
    def _target(self, run: _Run) -> Path:
        if self.out.suffix in (".h5", ".hdf5"):
            return self.out
        stamp = dt.datetime.fromtimestamp(run.start["time"]).strftime("%Y%m%d-%H%M%S")
        plan = re.sub(r"[^A-Za-z0-9_.-]+", "-", str(run.start.get("plan_name", "bluesky"))).strip("-") or "bluesky"
        return self.out / f"{stamp}_{plan}_{run.start['uid'][:8]}.h5"

    def _open(self, run: _Run, descriptor: dict) -> None:
        path = self._target(run)
        if path.exists() or path.is_symlink():
            raise FileExistsError(f"{path} already exists; the Bluesky run {run.start['uid']} was not written "
                                  "(nothing was overwritten): give RunFileWriter another file or a folder")
        config = _flyer_config(descriptor)
        rig = self.rig
        bench = getattr(rig, "bench", None)
        link = getattr(getattr(rig, "session", None), "link", None)
        ident = link.identity if link is not None else None
        start = run.start
        plan_args = {k: start[k] for k in ("plan_name", "plan_type", "plan_args", "scan_id", "uid") if k in start}
        protocol_text = config.get("protocol") or (
            "# A Bluesky run written by tsa_bench.bluesky.RunFileWriter (not a tsa-bench protocol)\n"
            + "".join(f"# {line}\n" for line in json.dumps(plan_args, indent=1, default=str).splitlines()))
        bench_text = config.get("bench") or (bench.source_text if bench is not None else "")
        meta = {k: v for k, v in start.items() if k not in ("time", "uid", "versions")}
        meta["bluesky_uid"] = start["uid"]
        rs = RunStart(
            plan_name=str(start.get("protocol") or start.get("plan_name", "bluesky")), protocol_text=protocol_text,
            protocol_path=config.get("protocol_path") or None, bench_text=bench_text,
            bench_path=config.get("bench_path") or (bench.path if bench is not None else None),
            backend=("sim" if link.simulated else "serial") if link is not None else "import",
            port=getattr(rig, "port", "") or "", identity=ident._asdict() if ident is not None else {},
            firmware=f"{ident.fw_major}.{ident.fw_minor}.{ident.fw_patch}" if ident is not None else "",
            n_segments=0, estimated_duration_s=0.0, metadata=meta, extra_columns=dict(run.extra))
        writer = RunWriter(path)
        writer.on_start(rs)
        run.writer, run.path = writer, path
        self.paths.append(path)
        writer.on_event(EventRecord(0.0, "bluesky_start", f"run {start['uid']} of plan "
                                                          f"{start.get('plan_name', '?')}"))

    # -- rows -------------------------------------------------------------------------
    def _rows(self, descriptor_uid: str, data: list[dict], stamps: list[dict], times: list[float],
              seq: list[int]) -> None:
        run = self._runs.get(self._desc_run.get(descriptor_uid, ""))
        if run is None or run.writer is None:
            return
        role = run.roles.get(descriptor_uid)
        desc = run.descriptors[descriptor_uid]
        keys = {k: quantity_of(dk.get("source", "")) for k, dk in desc["data_keys"].items()}
        units = {k: dk.get("units") for k, dk in desc["data_keys"].items()}
        if role == "segments":
            for d in data:
                q = {keys[k]: v for k, v in d.items()}
                run.writer.on_segment(SegmentRecord(
                    int(q["segment_index"]), str(q["segment_kind"]), float(q["segment_t_start"]),
                    float(q["segment_t_end"]), json.loads(q["segment_params"]), str(q["segment_source"]),
                    None if int(q["segment_cycle"]) < 0 else int(q["segment_cycle"]), bool(q["segment_completed"])))
        elif role == "events":
            for d in data:
                q = {keys[k]: v for k, v in d.items()}
                run.writer.on_event(EventRecord(float(q["event_t"]), str(q["event_kind"]), str(q["event_detail"])))
        elif role == "samples":
            rows = [self._row(run, d, s, t, n, keys, units) for d, s, t, n in zip(data, stamps, times, seq)]
            cols = _columns(rows)
            for name in run.extra:
                cols[name] = np.array([r.get(name, math.nan) for r in rows], dtype="f8")
            run.writer.on_samples(SampleBlock(cols))
            run.rows += len(rows)

    def _row(self, run: _Run, data: dict, stamps: dict, time_s: float, seq_num: int, keys: dict,
             units: dict) -> dict[str, float]:
        q: dict[str, float] = {}
        for key, value in data.items():
            quantity = keys.get(key)
            if value is None:     # NaN as JSON lines carry it
                continue
            if quantity is None:
                name = _column_name(key)
                if name in run.extra:
                    q[name] = float(value)
                continue
            if quantity == "load" and units.get(key) == "g":
                value = float(value) * G_N_PER_G
            q[quantity] = value
        acq = None
        if self.rig is not None:
            for key, quantity in keys.items():
                if quantity is not None and key in stamps:
                    acq = self.rig.acquisition_at(stamps[key])
                    if acq is not None:
                        break
        if acq is not None:
            for name, value in (("device_time", acq.t_s), ("turns", acq.turns), ("length", acq.length_mm),
                                ("resistance", acq.resistance_ohm), ("heater_voltage", acq.heater_V),
                                ("load", acq.load_g * G_N_PER_G), ("step_position", acq.step_position)):
                q.setdefault(name, value)
        if "t" in q:
            t = float(q["t"])
        elif "device_time" in q:
            if run.t0 is None:
                run.t0 = float(q["device_time"])
            t = float(q["device_time"]) - run.t0
        else:
            t = time_s - run.start["time"]
        if not t > run.t_last:   # the contract: strictly increasing; never reorder what was read
            t = math.nextafter(run.t_last, math.inf)
        run.t_last = t
        turns = float(q.get("turns", math.nan))
        length, resistance = float(q.get("length", math.nan)), float(q.get("resistance", math.nan))
        flags = (msg.AdcFlags.POSITION_INVALID if length != length else 0) | \
            (msg.AdcFlags.RESISTANCE_NOT_MEASURED if resistance != resistance else 0)
        spt = self.rig.bench.steps_per_turn if self.rig is not None else 0
        step = q.get("step_position", round(turns * spt) if spt and turns == turns else 0)
        row = {"t": t, "turns": turns, "length": length, "resistance": resistance,
               "heater_voltage": float(q.get("heater_voltage", math.nan)), "load": float(q.get("load", math.nan)),
               "segment": int(q.get("segment", -1)), "motor_moving": int(q.get("motor_moving", 0)),
               "counter": int(q.get("counter", seq_num)), "step_position": int(step), "position_raw": 0,
               "resistance_raw": 0, "adc_flags": int(flags)}
        row.update({k: v for k, v in q.items() if k in run.extra})
        return row

    def _t_now(self, run: _Run, wall: float) -> float:
        return max(run.t_last, 0.0) if run.rows else max(0.0, wall - run.start["time"])


def _column_name(key: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]+", "_", key).strip("_") or "value"


def _flyer_config(descriptor: dict) -> dict[str, str]:
    """A protocol flyer's configuration in a descriptor (protocol and bench texts), by quantity."""
    out: dict[str, str] = {}
    for cfg in descriptor.get("configuration", {}).values():
        for key, dk in cfg.get("data_keys", {}).items():
            quantity = quantity_of(dk.get("source", ""))
            if quantity in ("protocol", "protocol_path", "bench", "bench_path"):
                out[quantity] = str(cfg.get("data", {}).get(key, ""))
    return out
