"""Every command that writes a file: an existing output is refused unless --force (run and
import files are never replaced), and a symbolic link planted where a command writes - the
output itself or a temporary name beside it - is never written through."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from click.testing import CliRunner

from tests.runner.helpers import plan_from_text, run_plan
from tests.store.test_reader_checks import PLAN
from tsa_bench.cli import main

SECRET = "the victim's file\n"


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("recorded")
    stop, _, path = run_plan(plan_from_text(PLAN), d)
    assert stop.exit_status == "success"
    res = CliRunner().invoke(main, ["fit", "polynomial", str(path), "--out", str(d / "model.json")])
    assert res.exit_code == 0, res.output
    return path, d / "model.json"


def _victim(tmp_path: Path) -> Path:
    victim = tmp_path / "victim.txt"
    victim.write_text(SECRET)
    return victim


def _plant(link: Path, victim: Path) -> Path:
    link.parent.mkdir(parents=True, exist_ok=True)
    os.symlink(victim, link)
    return link


def _invoke(*args: str):
    return CliRunner().invoke(main, [str(a) for a in args])


# command -> (arguments with {out} for the output file, the output file name)
FILE_OUTPUTS = {
    "fit": (["fit", "polynomial", "{run}", "--out", "{out}"], "m.json"),
    "predict": (["predict", "{model}", "{run}", "--write-prediction", "{out}"], "p.h5"),
    "diagnose --json": (["diagnose", "{run}", "--out", "{fresh}", "--json", "{out}", "-q", "--max-causes", "0"],
                        "d.json"),
    "export --documents": (["export", "{run}", "--documents", "--output", "{out}"], "d.jsonl"),
}


@pytest.mark.parametrize("command", list(FILE_OUTPUTS))
def test_a_file_output_is_not_overwritten_without_force_nor_written_through_a_link(recorded, tmp_path, command):
    run, model = recorded
    args, name = FILE_OUTPUTS[command]
    out = tmp_path / name

    calls = []

    def call(*extra):
        calls.append(1)   # diagnose's report folder: a new one each time (its own refusal is tested below)
        fresh = tmp_path / f"report{len(calls)}"
        return _invoke(*[a.format(run=run, model=model, out=out, fresh=fresh) for a in args], *extra)

    out.write_text("earlier\n")
    res = call()
    assert res.exit_code == 2 and "already exists" in res.output and "--force" in res.output, res.output
    assert out.read_bytes() == b"earlier\n"
    res = call("--force")
    assert res.exit_code == 0 and out.read_bytes() != b"earlier\n", res.output
    out.unlink()
    victim = _victim(tmp_path)
    _plant(out, victim)
    res = call()
    assert res.exit_code == 2 and "symbolic link" in res.output, res.output
    assert victim.read_text() == SECRET
    res = call("--force")   # the link itself is replaced; its target is never written
    assert res.exit_code == 0 and not out.is_symlink() and victim.read_text() == SECRET, res.output


def test_export_refuses_existing_csv_and_never_writes_through_a_link(recorded, tmp_path):
    run, _ = recorded
    res = _invoke("export", run, "--csv", "--out", tmp_path)
    assert res.exit_code == 0, res.output
    samples = tmp_path / "run.samples.csv"
    before = samples.read_text()
    res = _invoke("export", run, "--csv", "--out", tmp_path)
    assert res.exit_code == 2 and "run.samples.csv already exists" in res.output and "--force" in res.output
    samples.unlink()
    victim = _victim(tmp_path)
    _plant(samples, victim)
    res = _invoke("export", run, "--csv", "--out", tmp_path, "--force")
    assert res.exit_code == 0 and victim.read_text() == SECRET and samples.read_text() == before, res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.events.csv", "run.samples.csv", "run.segments.csv",
                                                           "victim.txt"]   # no temporary left


@pytest.mark.parametrize("command", ["report", "diagnose"])
def test_a_report_folder_with_files_is_refused_without_force_and_links_in_it_are_replaced(recorded, tmp_path, command):
    run, _ = recorded
    out = tmp_path / "rep"
    args = ["report", run, "--out", out] if command == "report" else ["diagnose", run, "--out", out, "-q",
                                                                      "--max-causes", "0"]
    res = _invoke(*args)
    assert res.exit_code == 0, res.output
    written = sorted(p.name for p in out.iterdir())
    res = _invoke(*args)
    assert res.exit_code == 2 and "already holds files" in res.output and "--force" in res.output, res.output
    victim = _victim(tmp_path)
    for name in written:   # a link planted at every name the command writes (figures, text, JSON)
        (out / name).unlink()
        _plant(out / name, victim)
    res = _invoke(*args, "--force")
    assert res.exit_code == 0 and victim.read_text() == SECRET, res.output
    assert not [p for p in out.iterdir() if p.is_symlink()] and sorted(p.name for p in out.iterdir()) == written
    linked = tmp_path / "linked"
    linked.symlink_to(out, target_is_directory=True)
    res = _invoke(*(a if a != out else linked for a in args), "--force")
    assert res.exit_code == 2 and "symbolic link" in res.output


def test_estimate_and_reproduce_refuse_existing_outputs_before_working(recorded, tmp_path):
    run, _ = recorded
    out = tmp_path / "e.json"
    out.write_text("earlier\n")
    res = _invoke("estimate", "--train", run, "--out", out)
    assert res.exit_code == 2 and "already exists" in res.output and out.read_text() == "earlier\n"
    figures = tmp_path / "figures"
    figures.mkdir()
    (figures / "chapter3.png").write_text("earlier\n")
    res = _invoke("reproduce", "--quick", "--chapter", "3", "--figures", figures)
    assert res.exit_code == 2 and "already holds files" in res.output


def test_run_and_import_never_replace_a_file_and_ignore_links_at_temporary_names(recorded, tmp_path):
    run, _ = recorded
    victim = _victim(tmp_path)
    out = tmp_path / "new.h5"
    for name in ("new.h5.live", "new.h5.live.tmp", "new.h5.writing"):   # the names a writer used to take
        _plant(tmp_path / name, victim)
    res = _invoke("run", Path(__file__).parents[2] / "configs/protocols/stiffness-3ply.yaml", "--output", out)
    assert res.exit_code == 0, res.output
    assert victim.read_text() == SECRET and out.stat().st_size > 10_000
    assert "live view disabled" in res.output   # the journal's name was taken by the planted link
    res = _invoke("run", Path(__file__).parents[2] / "configs/protocols/stiffness-3ply.yaml", "--output", victim)
    assert res.exit_code == 2 and "already exists" in res.output and victim.read_text() == SECRET
    src = tmp_path / "lab.csv"
    src.write_text("t [s],turns [turn],length [mm]\n0,0,250\n0.1,1,249\n0.2,2,248\n")
    for name in ("imported.h5", "imported.h5.importing"):
        _plant(tmp_path / name, victim)
    res = _invoke("import", src, "--out", tmp_path / "imported.h5")
    assert res.exit_code == 2 and "already exists" in res.output and victim.read_text() == SECRET
    (tmp_path / "imported.h5").unlink()
    res = _invoke("import", src, "--out", tmp_path / "imported.h5")
    assert res.exit_code == 0 and not (tmp_path / "imported.h5").is_symlink() and victim.read_text() == SECRET


def test_jog_never_replaces_a_file(tmp_path):
    victim = _victim(tmp_path)
    for target in (victim, _plant(tmp_path / "link.h5", victim)):
        res = CliRunner().invoke(main, ["jog", "--port", "sim://", "--script", "-", "--output", str(target)],
                                 input="+1\nquit\n")
        assert res.exit_code == 2 and "already exists" in res.output, res.output
    assert victim.read_text() == SECRET
    res = CliRunner().invoke(main, ["jog", "--port", "sim://", "--script", "-", "--out", str(tmp_path / "runs")],
                             input="+1\nquit\n")
    assert res.exit_code == 0, res.output
    assert [p.suffix for p in (tmp_path / "runs").iterdir()] == [".h5"]   # the session's file alone


def test_a_file_that_appears_while_an_output_is_written_is_not_replaced(tmp_path):
    """Between the early check and the publishing rename another process creates the output
    (a file or a link): without force the output is refused and the newcomer kept; with
    force a link is replaced, never followed. No temporary file is left either way."""
    from tsa_bench.outputs import OutputExists, open_new, writing

    victim = _victim(tmp_path)
    out = tmp_path / "out.txt"
    for planted in ("file", "link"):
        with pytest.raises(OutputExists):
            with writing(out) as tmp:
                with open_new(tmp) as f:
                    f.write(b"mine\n")
                out.write_text("theirs\n") if planted == "file" else _plant(out, victim)
        assert (out.read_text() == "theirs\n") if planted == "file" else out.is_symlink()
        assert victim.read_text() == SECRET and sorted(p.name for p in tmp_path.iterdir()) == ["out.txt", "victim.txt"]
        out.unlink()
    with writing(out, force=True) as tmp:
        with open_new(tmp) as f:
            f.write(b"mine\n")
        _plant(out, victim)
    assert not out.is_symlink() and out.read_text() == "mine\n" and victim.read_text() == SECRET


def test_an_import_whose_temporary_file_is_swapped_for_a_link_writes_nothing_through_it(tmp_path, monkeypatch):
    """The import writer reopens its temporary file by name (HDF5 opens by name) to add the
    columns: a link swapped in for it just before is refused; the file it points at is not
    written and no output appears."""
    import h5py

    from tsa_bench.importers import writer

    victim = tmp_path / "victim.h5"
    with h5py.File(victim, "w") as f:
        f["secret"] = [1.0, 2.0]
    before = victim.read_bytes()
    opened = h5py.File

    def swap_then_open(name, mode="r", *args, **kw):
        if str(name).endswith(".importing") and mode == "a":
            os.unlink(name)
            os.symlink(victim, name)
        return opened(name, mode, *args, **kw)

    monkeypatch.setattr(writer.h5py, "File", swap_then_open)
    src = tmp_path / "lab.csv"
    src.write_text("t [s],turns [turn],length [mm]\n0,0,250\n0.1,1,249\n0.2,2,248\n")
    res = _invoke("import", src, "--out", tmp_path / "imported.h5")
    assert res.exit_code != 0 and "replaced while it was written" in res.output, res.output
    assert victim.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lab.csv", "victim.h5"]
