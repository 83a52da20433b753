"""Commands that work for a while refuse an output path they cannot write before they start."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.cli.exits import unwritable_reason


@pytest.mark.parametrize("args", [
    ["reproduce", "--quick", "--figures", "{blocker}/figures"],
    ["fit", "polynomial", "{missing}", "--out", "{blocker}/m.json"],
    ["estimate", "--train", "{missing}", "--out", "{blocker}/m.json"],
])
def test_an_output_under_a_file_is_refused_at_once_naming_it(tmp_path, args):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    argv = [a.format(blocker=blocker, missing=tmp_path / "nothing.h5") for a in args]
    res = CliRunner().invoke(main, argv)
    assert res.exit_code == 2, res.output
    assert f"{blocker} is not a folder" in res.output and "Traceback" not in res.output
    assert blocker.read_text() == "not a folder" and sorted(p.name for p in tmp_path.iterdir()) == ["a-file"]


def test_the_reason_names_what_is_wrong_and_nothing_is_created(tmp_path):
    assert unwritable_reason(tmp_path / "new" / "deeper") is None        # made later, from a writable folder
    assert unwritable_reason(tmp_path) is None
    f = tmp_path / "file.json"
    f.write_text("{}")
    assert unwritable_reason(f) is None                                   # an existing file may be replaced
    assert unwritable_reason(f / "x") == f"{f} is not a folder"
    assert not (tmp_path / "new").exists()
