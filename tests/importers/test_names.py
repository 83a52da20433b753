"""Names as labs write them: time guessed from common names (and said so), extra names that contain a known one,
and an import that places no measured column refused (issue 29, items 7 and 10)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.importers.fixtures import run_import
from tsa_bench.store import read_run

ROWS = "".join(f"{k * 0.5:g},{100 + k}\n" for k in range(6))


@pytest.mark.parametrize("header,extra", [("Elapsed_s", ()), ("Timestamp", ("--units", "Timestamp=s")),
                                          ("X_Value", ("--units", "t=s")), ("Elapsed Time (s)", ())])
def test_time_is_guessed_from_common_names_and_said_so(tmp_path, header, extra):
    res, out = run_import(tmp_path, f"{header},length [mm]\n" + ROWS, *extra)
    assert res.exit_code == 0, res.output
    assert f"t guessed from column '{header}' (a common name for time; --map t=COLUMN chooses another)" in res.output
    assert np.allclose(read_run(out).samples["t"], np.arange(6) * 0.5)


def test_a_guessed_time_without_a_unit_asks_for_one(tmp_path):
    res, out = run_import(tmp_path, "X_Value,length [mm]\n" + ROWS)
    assert res.exit_code == 2 and not out.exists()
    assert "column 'X_Value' (t) has no unit" in res.output and "--units t=UNIT" in res.output


def test_two_time_like_columns_are_not_guessed_between(tmp_path):
    res, out = run_import(tmp_path, "Elapsed_s,Timestamp [s],length [mm]\n" + "".join(f"{k},{k},{k}\n" for k in range(3)))
    assert res.exit_code == 2 and not out.exists()
    assert "several could be time ('Elapsed_s', 'Timestamp [s]')" in res.output


def test_names_built_from_a_known_one_are_extra_columns(tmp_path):
    text = "t [s],length [mm],a,b\n" + "".join(f"{k},{100 + k},{k * 2},{k * 3}\n" for k in range(4))
    res, out = run_import(tmp_path, text, "--map", "t_force=a,t_position=b", "--units", "t_force=s,t_position=s")
    assert res.exit_code == 0, res.output
    run = read_run(out)
    assert np.allclose(run.samples["t_force"], [0, 2, 4, 6]) and run.units["t_position"] == "s"
    res, out = run_import(tmp_path, None, "--map", "lenght=a", out="b.h5")
    assert res.exit_code == 2 and "did you mean 'length'?" in res.output


def test_an_import_that_places_no_measured_column_writes_nothing(tmp_path):
    text = "".join(f"{k},{k * 2}\n" for k in range(474))
    res, out = run_import(tmp_path, text, "--no-header", "--sample-period", "0.1")
    assert res.exit_code == 2 and not out.exists() and not list(tmp_path.glob("*.h5*"))
    assert "no measured column placed, only synthetic time" in res.output and "--map length=COLUMN" in res.output
    res, out = run_import(tmp_path, "t [s],note\n0,a\n1,b\n", out="b.h5")
    assert res.exit_code == 2 and not out.exists() and "no measured column placed, only t" in res.output
    assert "column 'note': not a contract column" in res.output


def test_a_date_time_column_guessed_as_time_says_what_t_must_be(tmp_path):
    res, out = run_import(tmp_path, "Timestamp,length [mm]\n2024-01-01 10:00:00,100\n2024-01-01 10:00:01,101\n",
                          "--units", "t=s")
    assert res.exit_code == 2 and not out.exists()
    assert "cannot parse '2024-01-01 10:00:00' as a number" in res.output
    assert "t must be a number of seconds" in res.output
