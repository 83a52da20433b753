"""Helpers for tests/report_diagnose: hand-built diagnose results of each verdict and minimal
run files (the engine is not run)."""

from __future__ import annotations

import h5py
import numpy as np

from tsa_bench.analysis import Candidate, DiagnoseResult, Gain, NamedCause
from tsa_bench.store import REQUIRED_COLUMNS


def _tests(structured_r: bool, after_structured: bool = False) -> dict:
    def one(structured, rms, follows=()):
        return {"structured": structured, "testable": True, "p": 1e-30 if structured else 0.4, "structured_rms": rms,
                "rms": rms + 0.001, "follows": list(follows), "jumps": 0, "ljung_box_p": 0.3}
    fl = [{"signal": "time_since_stop", "share": 0.91, "p": 1e-20, "r2": 0.5}]
    return {"before": {"length": one(False, 0.004), "resistance": one(structured_r, 0.031 if structured_r else 1e-4,
                                                                       fl if structured_r else ())},
            "after": {"length": one(False, 0.004), "resistance": one(after_structured, 0.02 if after_structured
                                                                     else 1e-4, fl if after_structured else ())}}


def build_result(n: int = 2000, verdict: str = "named", with_signal: bool = True) -> DiagnoseResult:
    """A plausible result on ``n`` samples for each verdict."""
    rng = np.random.default_rng(0)
    t = np.arange(n) * 0.1
    heldout = (t >= t[int(0.4 * n)]) & (t < t[int(0.7 * n)])
    length = 280 - 0.5 * np.sin(t / 20)
    since_stop = np.mod(t, 17.0)
    transient = -0.02 * np.log(since_stop + 1e-2) if verdict in ("named", "unexplained") else 0.0
    r_true = 5.8 + 0.01 * np.sin(t / 20) + transient
    named = verdict == "named"
    series = {"t": t, "heldout": heldout,
              "length_measured": length + rng.normal(0, 0.05, n), "length_before": length, "length_after": length,
              "resistance_measured": r_true + rng.normal(0, 0.001, n),
              "resistance_before": 5.8 + 0.01 * np.sin(t / 20),
              "resistance_after": r_true if named else 5.8 + 0.01 * np.sin(t / 20)}
    if named and with_signal:
        series["cause_signal"] = transient
    causes = [NamedCause("resistance_transient_decay", "stretched exponential", "resistance_transient_stretched",
                         "resistance", 0.98, 0.87, 412.5, (301.2, 533.0), {"length": 0.002, "resistance": 0.966},
                         {"resistance_transient_stretched.amp_ohm": 0.0271,
                          "resistance_transient_stretched.time_constant_s": 9.5,
                          "resistance_transient_stretched.beta": 0.61})] if named else []
    cands = [Candidate("resistance_transient_stretched", "effect", 0.74,
                       {"family": "resistance_transient_decay", "form": "stretched exponential",
                        "refit": {"passed": named, "reason": "passes" if named else "not significant",
                                  "heldout": {"improvement_noise_var": {"pooled": 412.5}}}}),
             Candidate("length_creep", "effect", 0.002, {"family": "length_creep", "form": "after load changes"})]
    gains = [Gain("length", 0.0512, 0.0511, 0.002),
             Gain("resistance", 0.0312, 0.00105, 0.966) if named else Gain("resistance", 0.0312, 0.0312, 0.0)]
    base = ["string_compliance", "radius_growth", "resistance_length", "sensor_noise"]
    summaries = {
        "named": "named: resistance_transient_decay (stretched exponential, confidence 0.98)",
        "explained": "explained: the calibrated model leaves only sensor noise (residual RMS length 0.051 mm, "
                     "resistance 0.00101 ohm)",
        "unexplained": "unexplained: resistance residual follows the time since the motor stopped (91 % of its "
                       "structure): not among the candidates",
        "model_mismatch": "model_mismatch: run.h5: no motor twist recorded (turns is all NaN); the model is driven "
                          "by the twist",
    }
    unexplained = [{"output": "resistance", "structured_rms": 0.031, "units": "ohm", "p": 1e-30, "follows": [],
                    "jumps": 0, "induced": False, "text": summaries["unexplained"][len("unexplained: "):]}] \
        if verdict == "unexplained" else []
    mismatch = [{"reason": summaries["model_mismatch"][len("model_mismatch: "):],
                 "remedy": "record or import a turns column (tsa-bench import --map turns=...)"}] \
        if verdict == "model_mismatch" else []
    calibrated = {"before": {"geometry.untwisted_length_mm": 248.3, "string_compliance.stiffness_N": 30.2,
                             "resistance_length.ohm_per_mm": 0.0151},
                  "after": {"geometry.untwisted_length_mm": 248.1, "string_compliance.stiffness_N": 30.1,
                            "resistance_length.ohm_per_mm": 0.0150,
                            **({"resistance_transient_stretched.amp_ohm": 0.0271} if named else {})}}
    return DiagnoseResult(
        verdict, summaries[verdict], causes, cands if verdict != "model_mismatch" else [],
        gains if verdict != "model_mismatch" else [], _tests(verdict in ("named", "unexplained"),
                                                             verdict == "unexplained")
        if verdict != "model_mismatch" else {},
        base, base + (["resistance_transient_stretched"] if named else []),
        calibrated if verdict != "model_mismatch" else {}, series if verdict != "model_mismatch" else {},
        ["hand-built result for the report tests"], unexplained=unexplained, mismatch=mismatch,
        noise={"length": {"rms": 0.05, "quantisation_step": 0.0}, "resistance": {"rms": 0.001,
                                                                                "quantisation_step": 0.0}},
        calibration={"judged": {"at_bound": [], "undetermined": []},
                     "final": {"at_bound": [], "undetermined": ["string_compliance.stiffness_N"]}},
        holdout={"spec": "default", "description": "contiguous blocks cut at segment boundaries"},
        provenance={"model": {"path": "configs/bench/sim-baseline.yaml"}})


def write_minimal_run(path, n: int = 50) -> None:
    """A contract-meeting run file (another tool might write it)."""
    with h5py.File(path, "w") as f:
        f.attrs["format"] = "tsa-bench/run"
        f.attrs["exit_status"] = "success"
        g = f.create_group("samples")
        for name, unit in REQUIRED_COLUMNS.items():
            g.create_dataset(name, data=np.arange(n, dtype=float) * (0.1 if name == "t" else 1.0)
                             ).attrs["units"] = unit
