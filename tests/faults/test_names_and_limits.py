"""Names and sizes a person can write that a file system or the memory cannot take: refused
(or, for a run's file name, shortened) with a clear message, never a traceback, never a
file written outside the folder asked for; `validate` refuses what `run` refuses."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.userfiles import DocumentError, YamlLimits, parse_yaml

ROOT = Path(__file__).resolve().parents[2]
STEPS = "defaults: {rate_turns_per_s: 2, accel_turns_per_s2: 20}\nsteps:\n  - move_to: {turns: 1}\n  - hold: {duration_s: 1}\n"


def _clean(res) -> str:
    assert "Traceback" not in res.output and (res.exception is None or isinstance(res.exception, SystemExit)), \
        res.output
    return res.output


def test_a_five_thousand_character_protocol_name_gives_a_shortened_run_file_name(tmp_path):
    name = "n" * 5000
    proto = tmp_path / "long.yaml"
    proto.write_text(f"name: {name}\n{STEPS}")
    assert CliRunner().invoke(main, ["validate", str(proto)]).exit_code == 0
    res = CliRunner().invoke(main, ["run", str(proto), "--out", str(tmp_path / "runs")])
    out = _clean(res)
    assert res.exit_code == 0, out
    (made,) = (tmp_path / "runs").glob("*.h5")
    assert len(made.name.encode()) <= 255 and re.fullmatch(r"\d{8}-\d{6}_n{80}\.h5", made.name), made.name
    from tsa_bench.store import read_run
    assert read_run(made).attrs["plan_name"] == name   # the name itself is kept whole in the file


@pytest.mark.parametrize("name, message", [("s" * 5000, "a name of 5,000 characters; at most 100"),
                                           ("..", "not '.' or '..'"), (".", "not '.' or '..'")])
def test_a_study_name_that_cannot_name_a_folder_is_refused(tmp_path, name, message):
    pytest.importorskip("pyarrow")
    pytest.importorskip("distributed")
    work = tmp_path / "work"
    work.mkdir()
    study = work / "s.yaml"
    study.write_text(f"study: '{name}'\nrunner: simulate\nbase: {{protocol: {{cycles: 2}}}}\n")
    cwd = os.getcwd()
    os.chdir(work)
    try:
        for args in (["sweep", str(study), "--dry-run"], ["sweep", str(study)]):
            res = CliRunner().invoke(main, args)
            out = _clean(res)
            assert res.exit_code == 2 and f"{study}:1:" in out and message in out, out
    finally:
        os.chdir(cwd)
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["s.yaml", "work"]   # nothing written anywhere


def test_validate_refuses_a_plant_seed_that_run_refuses(tmp_path):
    bench = tmp_path / "b.yaml"
    bench.write_text((ROOT / "configs/bench/sim.yaml").read_text().replace("  seed: ", "  seed: -1e300 #", 1))
    proto = tmp_path / "p.yaml"
    proto.write_text(f"name: p\n{STEPS}")
    for args in (["validate", str(proto), "--bench", str(bench)],
                 ["run", str(proto), "--bench", str(bench), "--output", str(tmp_path / "r.h5")]):
        res = CliRunner().invoke(main, args)
        out = _clean(res)
        assert res.exit_code == 2 and "plant: 'seed' must be an integer >= 0 or null, got -1e+300" in out, out
    assert not (tmp_path / "r.h5").exists()


def test_a_protocol_with_a_million_value_list_is_refused_for_its_size(tmp_path):
    proto = tmp_path / "big.yaml"
    proto.write_text(f"name: big\n{STEPS}metadata:\n  notes: [" + ",".join(["1"] * 1_000_000) + "]\n")
    assert 1_900_000 < proto.stat().st_size < 4_000_000
    res = CliRunner().invoke(main, ["validate", str(proto)])
    out = _clean(res)
    assert res.exit_code == 2 and f"{proto}:7:" in out and "holds more than 200,000 values" in out, out
    assert "alias" not in out


def test_the_composer_counts_values_too_without_libyaml(monkeypatch):
    import yaml

    monkeypatch.setattr(yaml, "__with_libyaml__", False)
    with pytest.raises(DocumentError, match="holds more than 1,000 values"):
        parse_yaml("a: [" + ",".join(["1"] * 2000) + "]\n", "x.yaml", YamlLimits(max_nodes=1000))
    assert parse_yaml("a: [" + ",".join(["1"] * 900) + "]\n", "x.yaml", YamlLimits(max_nodes=1000)).data()["a"][0] == 1
