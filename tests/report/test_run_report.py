"""`tsa-bench report`: figures chosen by content for every shipped protocol, damaged runs."""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.report.run_analysis import stiffness_points
from tsa_bench.report.run_report import select_figures, write_run_report
from tsa_bench.store import read_run

#: What each shipped protocol is for, so the figure of its thesis experiment must appear.
EXPECTED = {
    "stiffness-3ply": {"stiffness"}, "stiffness-4ply": {"stiffness"},
    "twist-sweep-3ply": {"loops", "resistance_length"}, "twist-sweep-4ply": {"loops", "resistance_length"},
    "twist-heat-4ply": {"loops", "voltage"},
    "twist-heat-grid": {"twist_heat", "voltage"}, "twist-heat-simultaneous": {"twist_heat"},
    "quasi-static-self-sensing": {"resistance_length", "transient"},
    "quasi-static-self-sensing-settled": {"resistance_length", "transient"},
    "transient-steps": {"transient"}, "lifetime": {"drift"},
    "track-length-training": {"resistance_length", "transient"},
    "estimate-load-training": {"resistance_length", "transient"},
    "estimate-load-changes": {"resistance_length", "transient"},
    "track-length-steps": {"tracking", "resistance_length"}, "track-length-loads": {"tracking"},
}
#: Protocols whose runs carry the runner's tracking columns (docs/run-format.md) beyond the contract.
TRACKING = {"track-length-steps", "track-length-loads"}
#: Figures a protocol's data cannot support (no load steps, no heating, no cycles, no twist).
FORBIDDEN = {
    "stiffness-3ply": {"loops", "voltage", "drift", "transient", "resistance_length"},
    "twist-sweep-3ply": {"voltage", "drift", "stiffness"},
    "twist-heat-4ply": {"drift", "stiffness", "twist_heat"},   # heated at full twist only
    "lifetime": {"voltage", "stiffness"},
}


def _png_ok(path) -> None:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000, path


def test_every_shipped_protocol_gets_its_thesis_figures(protocol_runs, tmp_path):
    assert set(protocol_runs) == set(EXPECTED), "a protocol was added or renamed: update EXPECTED"
    for name, run_file in protocol_runs.items():
        rep = write_run_report(run_file, tmp_path / name)
        kinds = {f.name for f in rep.figures}
        assert "timeseries" in kinds and EXPECTED[name] <= kinds, (name, kinds)
        assert not (FORBIDDEN.get(name, set()) & kinds), (name, kinds)
        assert set(rep.skipped) | kinds == {"timeseries", "stiffness", "loops", "voltage", "resistance_length",
                                            "transient", "drift", "tracking", "extras", "extras_xy", "twist_heat"}
        if name in TRACKING:  # the estimate, target and controller state columns
            assert {"tracking", "extras"} <= kinds
        else:
            assert not {"extras", "extras_xy", "tracking"} & kinds  # only contract columns
        for fig in rep.figures:
            _png_ok(fig.path)
        page = rep.index.read_text()
        for fig in rep.figures:
            assert f"src='{fig.name}.png'" in page
        assert name in page and "<th>Exit status</th>" in page and "<th>exit_status</th>" not in page


def test_stiffness_matches_the_simulated_string(protocol_runs):
    run = read_run(protocol_runs["stiffness-4ply"])
    pts = stiffness_points(run)
    assert len(pts) == 9  # 5 loads up, 4 down, unloaded rests give L0
    assert sum(p.rising for p in pts) == 5
    k = np.array([p.k for p in pts])
    # K = F L0 / (L - L0) must be recomputable from the points themselves and be a stiffness (N)
    assert np.allclose(k, [p.load * p.l0 / (p.length - p.l0) for p in pts])
    assert np.all((k > 5) & (k < 200))


def test_cli_report_and_html_escaping(protocol_runs, tmp_path):
    src = tmp_path / "evil.h5"
    shutil.copy(protocol_runs["twist-sweep-3ply"], src)
    with h5py.File(src, "a") as f:
        f.attrs["plan_name"] = "<script>alert(1)</script>"
        f.attrs["metadata"] = '{"note": "a & b <b>"}'
    res = CliRunner().invoke(main, ["report", str(src), "--out", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    page = (tmp_path / "out" / "index.html").read_text()
    assert "<script>" not in page and "&lt;script&gt;" in page and "a &amp; b &lt;b&gt;" in page
    assert "wrote" in res.output and "no voltage figure" in res.output


def test_bad_file_is_a_clear_error(tmp_path):
    bad = tmp_path / "x.h5"
    bad.write_text("not hdf5")
    res = CliRunner().invoke(main, ["report", str(bad)])
    assert res.exit_code == 2 and "x.h5" in res.output and "not a readable HDF5 file" in res.output


def _damaged(src, dst, *, status: str, keep: float = 1.0, nan_columns: tuple = ()) -> None:
    shutil.copy(src, dst)
    with h5py.File(dst, "a") as f:
        f.attrs["exit_status"] = status
        f.attrs["reason"] = "test: damaged copy"
        n = len(f["samples/t"])
        for ds in f["samples"].values():
            ds.resize((int(n * keep),))
        for name in nan_columns:
            f["samples"][name][...] = np.nan


@pytest.mark.parametrize("status,keep,nans,absent", [
    ("aborted", 0.5, (), set()),
    ("running", 0.3, (), set()),                       # killed: exit_status never written
    ("failed", 1.0, ("resistance",), {"resistance_length", "transient"}),
    ("success", 1.0, ("length", "resistance"), {"loops", "resistance_length", "transient"}),
    ("failed", 0.0, (), {"timeseries"}),
])
def test_failed_aborted_killed_and_nan_runs(protocol_runs, tmp_path, status, keep, nans, absent):
    src = tmp_path / "damaged.h5"
    _damaged(protocol_runs["twist-sweep-4ply"], src, status=status, keep=keep, nan_columns=nans)
    rep = write_run_report(src, tmp_path / "rep")
    kinds = {f.name for f in rep.figures}
    assert not (absent & kinds), kinds
    assert set(rep.skipped) >= absent
    page = rep.index.read_text()
    if status != "success":
        assert "class=\"bad\"" in page and (status if status != "running" else "killed") in page
    if keep == 0.0:
        assert not rep.figures and "no samples" in page
    else:
        assert "timeseries" in kinds
    chosen, _ = select_figures(read_run(src))
    assert chosen == [f.name for f in rep.figures]
