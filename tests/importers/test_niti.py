"""The public NiTi (Flexinol) data set imports as it is published: no header edit, no conversion by hand."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from tests.report.conftest import ROOT
from tsa_bench.cli import main
from tsa_bench.store import read_run

DATA = ROOT.parent / "shared" / "data" / "niti_flexinol"
STRESSES = (50, 100, 150, 172, 200)
pytestmark = pytest.mark.skipif(not (DATA / "filtered_data_50MPa.txt").exists(),
                                reason=f"the NiTi data set is read from {DATA}, which is absent here")


def test_every_niti_file_imports_with_options_only(tmp_path):
    for s in STRESSES:
        out = tmp_path / f"niti_{s}.h5"
        res = CliRunner().invoke(main, ["import", str(DATA / f"filtered_data_{s}MPa.txt"), "--units",
                                        "temperature=degC,stress=MPa", "--sample-period", "1", "--out", str(out)])
        assert res.exit_code == 0, res.output
        assert "column 'Temperature' -> temperature (extra column, picked up) [degC]" in res.output
        assert "column 'Strain' -> strain (extra column, picked up) [1]" in res.output
        run = read_run(out)
        assert run.units["stress"] == "MPa" and abs(np.mean(run.samples["stress"]) - s) < 0.05 * s
        assert 0.0 < np.nanmean(run.samples["strain"]) < 0.1 and len(run) > 100
        assert "row index x 1 s" in json.loads(run.attrs["metadata"])["time"]
    fit = CliRunner().invoke(main, ["fit", "preisach", str(tmp_path / "niti_100.h5"), "--input", "temperature",
                                    "--output", "strain", "--out", str(tmp_path / "m.json")])
    assert fit.exit_code == 0, fit.output
    assert fit.output.splitlines()[0].startswith("note: ") and "has no segments" in fit.output.splitlines()[0]
