"""A measured force (load cell) is its own channel, never the declared load that fit counts and selects by."""

from __future__ import annotations

import numpy as np
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.store import read_run


def _load_cell_csv(tmp_path, header: str):
    rng = np.random.default_rng(3)
    t = np.arange(300) * 0.1
    turns = np.floor(t / 3.0) * 2  # ten holds
    length = 250 - 0.8 * turns + rng.normal(0, 0.01, 300)
    force = 2.0 + 0.05 * turns + rng.normal(0, 0.003, 300)
    src = tmp_path / "cell.csv"
    src.write_text(f"t [s],turns [turn],length [mm],{header}\n"
                   + "".join(f"{a:.6g},{b:.6g},{c:.8g},{d:.8g}\n" for a, b, c, d in zip(t, turns, length, force)))
    return src


def test_a_load_cell_column_is_force_not_load(tmp_path):
    src = _load_cell_csv(tmp_path, "Load cell (N)")
    res = CliRunner().invoke(main, ["import", str(src), "--out", str(tmp_path / "c.h5")])
    assert res.exit_code == 0, res.output
    assert "column 'Load cell (N)' -> force (extra column, picked up) [N]" in res.output
    run = read_run(tmp_path / "c.h5")
    assert np.isnan(run.samples["load"]).all() and run.units["force"] == "N" and run.samples["force"].std() > 0
    fit = CliRunner().invoke(main, ["fit", "polynomial", str(tmp_path / "c.h5"), "--out", str(tmp_path / "m.json")])
    assert fit.exit_code == 0, fit.output
    assert "loads (" not in fit.output  # no "2265 loads": a measured force is not counted as declared loads
    assert "has no declared load; its measured force (force, " in fit.output
    sel = CliRunner().invoke(main, ["fit", "polynomial", str(tmp_path / "c.h5"), "--load-g", "200",
                                    "--out", str(tmp_path / "s.json")])
    assert sel.exit_code == 2 and "measured force (the 'force' column) is not a declared load" in sel.output
    as_io = CliRunner().invoke(main, ["fit", "polynomial", str(tmp_path / "c.h5"), "--input", "turns",
                                      "--output", "force", "--out", str(tmp_path / "f.json")])
    assert as_io.exit_code == 0, as_io.output
    diag = CliRunner().invoke(main, ["diagnose", str(tmp_path / "c.h5"), "--outputs", "length", "-q",
                                     "--out", str(tmp_path / "dg")])
    assert diag.exit_code == 0, diag.output
    assert diag.output.splitlines()[0].startswith(f"diagnose: note: {tmp_path / 'c.h5'} has a measured force")


def test_a_force_mapped_as_load_is_flagged(tmp_path):
    src = _load_cell_csv(tmp_path, "F [N]")
    res = CliRunner().invoke(main, ["import", str(src), "--map", "load=F", "--out", str(tmp_path / "l.h5")])
    assert res.exit_code == 0, res.output
    assert "the declared load takes more than 20 values" in res.output and "--map force=COLUMN" in res.output
