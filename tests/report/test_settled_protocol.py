"""The thesis's quasi-static protocol written with hold_until_settled: shorter on the
simulated bench, with the same end values of every rotation."""

from __future__ import annotations

import numpy as np

from tsa_bench.store import read_run


def _rest_ends(path, kind: str):
    """(twist, duration, resistance, length) at the end of every rest of ``kind`` lasting > 100 s
    or settling: means over its last 5 s."""
    run = read_run(path)
    s = run.samples
    out = []
    for row in run.segments:
        k = row["kind"].decode()
        if k != kind or (k == "hold" and row["t_end"] - row["t_start"] < 100):
            continue
        m = (s["t"] > row["t_end"] - 5) & (s["t"] <= row["t_end"])
        out.append((float(s["turns"][m][-1]), float(row["t_end"] - row["t_start"]),
                    float(np.nanmean(s["resistance"][m])), float(np.nanmean(s["length"][m]))))
    return run, out


def test_settled_quasi_static_is_shorter_with_the_same_end_values(protocol_runs):
    fixed_run, fixed = _rest_ends(protocol_runs["quasi-static-self-sensing"], "hold")
    settled_run, settled = _rest_ends(protocol_runs["quasi-static-self-sensing-settled"], "settle")
    assert len(fixed) == len(settled) == 30
    assert [f[0] for f in fixed] == [s[0] for s in settled]                    # the same rotations
    assert all(abs(f[1] - 180) < 0.01 for f in fixed) and all(s[1] < 175 for s in settled)  # each ends early
    assert settled_run.samples["t"][-1] < 0.9 * fixed_run.samples["t"][-1]    # the whole run is shorter
    for f, s in zip(fixed, settled):                                         # at the same steady state
        assert abs(f[2] - s[2]) < 0.003 and abs(f[3] - s[3]) < 0.3, (f, s)
