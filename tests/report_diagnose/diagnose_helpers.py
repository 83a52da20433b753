"""Helpers for tests/report_diagnose: hand-built diagnose results, minimal run files (the engine is not needed).

When tsa_bench.analysis exists its DiagnoseResult/Candidate/Gain are used, so the tests
also check the report against the real classes; otherwise stand-ins with the same
fields (the API agreed in issue 5) are used.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import h5py
import numpy as np
from tsa_bench.store import REQUIRED_COLUMNS


@dataclass
class _Candidate:
    name: str
    kind: str
    score: float
    evidence: dict


@dataclass
class _Gain:
    output: str
    heldout_rmse_before: float
    heldout_rmse_after: float
    relative: float


@dataclass
class _DiagnoseResult:
    cause: str | None
    causes: list
    candidates: list
    gain: list
    residual_tests: dict
    model_effects_before: list
    model_effects_after: list
    calibrated: dict
    series: dict
    notes: list = field(default_factory=list)

    def to_json(self) -> dict:
        d = dataclasses.asdict(self)
        d.pop("series")
        return d


def _classes():
    try:
        from tsa_bench.analysis import Candidate, DiagnoseResult, Gain
        return Candidate, Gain, DiagnoseResult
    except ImportError:  # engine not there (yet): stand-ins with the agreed fields
        return _Candidate, _Gain, _DiagnoseResult


def build_result(n: int = 2000, cause: str | None = "resistance_transient_decay", with_signal: bool = True):
    """A plausible result on ``n`` samples: resistance residual explained by the cause, or clean."""
    Candidate, Gain, DiagnoseResult = _classes()
    rng = np.random.default_rng(0)
    t = np.arange(n) * 0.1
    heldout = t >= t[int(0.7 * n)]
    length = 280 - 0.5 * np.sin(t / 20)
    since_stop = np.mod(t, 17.0)
    transient = -0.02 * np.log(since_stop + 1e-2)
    r_true = 5.8 + 0.01 * np.sin(t / 20) + (transient if cause else 0)
    series = {
        "t": t, "heldout": heldout,
        "length_measured": length + rng.normal(0, 0.05, n), "length_before": length, "length_after": length,
        "resistance_measured": r_true + rng.normal(0, 0.001, n),
        "resistance_before": 5.8 + 0.01 * np.sin(t / 20), "resistance_after": r_true,
    }
    if cause and with_signal:
        series["cause_signal"] = since_stop
    cands = [
        Candidate("resistance_transient_decay", "effect", 412.5 if cause else 1.2,
                  {"output": "resistance", "delta_bic": -412.5 if cause else 3.0, "err": 0.61 if cause else 0.001}),
        Candidate("time_since_stop", "signal", 300.1 if cause else 0.9, {"output": "resistance", "err": 0.44}),
        Candidate("length_creep", "effect", 2.0, {"output": "length", "delta_bic": 4.1, "err": 0.002}),
    ]
    structured_r = bool(cause)
    tests = {
        "before": {
            "length": {"ljung_box_p": 0.41, "structured": False, "xcorr": {"turns": (0.01, 0.03)}},
            "resistance": {"ljung_box_p": 1e-30 if cause else 0.3, "structured": structured_r,
                           "xcorr": {"time_since_stop": (0.52 if cause else 0.01, 0.03), "turns": (0.02, 0.03)}},
        },
        "after": {
            "length": {"ljung_box_p": 0.40, "structured": False, "xcorr": {"turns": (0.01, 0.03)}},
            "resistance": {"ljung_box_p": 0.22, "structured": False, "xcorr": {"time_since_stop": (0.01, 0.03)}},
        },
    }
    base = ["string_compliance", "radius_growth", "resistance_length", "sensor_noise"]
    gains = [Gain("length", 0.0512, 0.0511, 0.002),
             Gain("resistance", 0.0312, 0.00105, 0.966) if cause else Gain("resistance", 0.00101, 0.00101, 0.0)]
    return DiagnoseResult(
        cause=cause, causes=[cause] if cause else [], candidates=cands, gain=gains, residual_tests=tests,
        model_effects_before=base, model_effects_after=base + ([cause] if cause else []),
        calibrated={"string_compliance": {"stiffness_N": 30.2}, "resistance_length": {"ohm_per_mm": 0.0151},
                    **({cause: {"b1_ohm": -0.0017, "b2_ohm": -0.0271}} if cause else {})},
        series=series, notes=["hand-built result for the report tests"])


def write_minimal_run(path, n: int = 50) -> None:
    """A contract-meeting run file (another tool might write it)."""
    with h5py.File(path, "w") as f:
        f.attrs["format"] = "tsa-bench/run"
        f.attrs["exit_status"] = "success"
        g = f.create_group("samples")
        for name, unit in REQUIRED_COLUMNS.items():
            g.create_dataset(name, data=np.arange(n, dtype=float) * (0.1 if name == "t" else 1.0)
                             ).attrs["units"] = unit
