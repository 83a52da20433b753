"""A public measured data set no one here wrote: NiTi (Flexinol) SMA loops at five stresses.

Read from ../shared/data/niti_flexinol/ beside the repository, never copied in; skipped with the reason when it is absent. The figures asserted are the
ones docs/niti-flexinol.md quotes (scripts/niti_flexinol.py prints them).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.models.transfer import transfer_study
from tsa_bench.store import read_run

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data" / "niti_flexinol"
STRESSES = (50, 100, 150, 172, 200)

pytestmark = pytest.mark.skipif(not (DATA / "filtered_data_50MPa.txt").exists(),
                                reason=f"the NiTi Flexinol data set is not at {DATA} (../shared beside the repository)")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    out = tmp_path_factory.mktemp("niti")
    runs = {}
    for s in STRESSES:
        path = out / f"niti_{s}.h5"
        res = CliRunner().invoke(main, ["import", str(DATA / f"filtered_data_{s}MPa.txt"),
                                        "--map", "temperature=Temperature,strain=Strain,stress=Stress",
                                        "--units", "temperature=degC,strain=1,stress=MPa",
                                        "--sample-period", "1", "--meta", f"stress_MPa={s}", "--out", str(path)])
        assert res.exit_code == 0, res.output
        runs[float(s)] = read_run(path)
    return runs


def test_each_file_round_trips_through_import_with_its_own_channels(runs, tmp_path):
    for s, run in runs.items():
        assert len(run) == 499 and run.attrs["backend"] == "import"
        assert {run.units[c] for c in ("temperature", "strain", "stress")} == {"degC", "1", "MPa"}
        assert abs(np.mean(run.samples["stress"]) - s) < 1.0  # the file's own stress channel
        raw = np.loadtxt(DATA / f"filtered_data_{s:g}MPa.txt", skiprows=1)
        assert np.array_equal(run.samples["temperature"], raw[:, 0]) and np.array_equal(run.samples["strain"], raw[:, 1])
        assert np.isnan(run.samples["length"]).all()  # no TSA length here: a different actuator
    exp = CliRunner().invoke(main, ["export", runs[100.0].path, "--csv", "--out", str(tmp_path)])
    assert exp.exit_code == 0
    back = tmp_path / "back.h5"
    assert CliRunner().invoke(main, ["import", str(tmp_path / "niti_100.samples.csv"), "--out", str(back)]).exit_code == 0
    b = read_run(back)
    for c in ("temperature", "strain", "stress"):
        assert b.units[c] == runs[100.0].units[c] and np.array_equal(b.samples[c], runs[100.0].samples[c])
    assert json.loads(b.attrs["metadata"])["extra_columns"]["stress"] == "MPa"


def test_preisach_beats_the_polynomial_and_transfers_by_interpolating_stress(runs):
    pre = transfer_study(runs, "preisach", "temperature", "strain", held_out=150.0)
    pol = transfer_study(runs, "polynomial", "temperature", "strain", held_out=150.0)
    assert set(pre.identification) == {50.0, 100.0, 172.0, 200.0} and pre.unit == "1"
    for c in pre.identification:  # identification: the loop is hysteretic, a cubic cannot follow it
        assert pre.identification[c] < 0.0007 and pol.identification[c] > 0.0035
        assert pol.identification[c] > 5 * pre.identification[c]
    # held out 150 MPa: the transformation temperatures move with stress, so the nearest stress's
    # Preisach model errs more than its own fit, interpolating between 100 and 172 MPa recovers most
    assert 0.0010 < pre.nearest < 0.0016 and pre.interpolated < 0.0009 and pre.pooled > pre.interpolated
    assert pre.interpolated < 0.25 * pol.interpolated
    assert 0.0035 < pol.nearest < 0.0045  # the polynomial is no worse held out: it never had the loop


def test_fit_says_it_used_the_whole_run_and_warns_about_parameters(runs, tmp_path):
    res = CliRunner().invoke(main, ["fit", "preisach", runs[200.0].path, "--input", "temperature", "--output",
                                    "strain", "--validate", runs[172.0].path, "--out", str(tmp_path / "m.json")])
    assert res.exit_code == 0, res.output
    assert "the whole run, 499 samples, was used" in res.output
    assert "211 parameters for 499 fitted samples" in res.output
