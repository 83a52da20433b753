"""What a run file says for its row, read from files nobody vouches for without hanging."""

from __future__ import annotations

import os

from tests.catalogue.helpers import cli, short_protocol
from tsa_bench.catalogue.runfiles import BoundedReader, file_facts, protocol_load_g, sha256_of


def test_a_file_that_hangs_the_reader_is_reported_and_the_next_one_still_read(tmp_path):
    good = tmp_path / "good.h5"
    assert cli("run", str(short_protocol(tmp_path)), "--output", str(good), "--catalogue", "none",
               "--meta", "sample=S5").returncode == 0
    stuck = tmp_path / "stuck.h5"
    os.mkfifo(stuck)          # opening it blocks for ever, as a looping HDF5 library would
    with BoundedReader(timeout_s=3.0) as reader:
        found = list(reader.read_all([good, stuck, good, tmp_path / "gone.h5"]))
    assert [p.name for p, _, _ in found] == ["good.h5", "stuck.h5", "good.h5", "gone.h5"]
    (_, a, _), (_, none, why), (_, b, _), (_, _, gone) = found
    assert none is None and "did not finish in 3 s" in why
    assert a == b and a["sample"] == "S5" and a["sha256"] == sha256_of(good) and a["status"] == "success"
    assert a == file_facts(good) and "gone.h5" in gone


def test_the_load_of_a_protocol_with_its_variables():
    text = "variables: {load_g: 550}\nload_g: $load_g\n"
    assert protocol_load_g(text) == 550.0 and protocol_load_g(text, {"load_g": 200}) == 200.0
    assert protocol_load_g("load_g: 120\n") == 120.0 and protocol_load_g("name: x\n") is None
    assert protocol_load_g("load_g: [\n") is None


def test_a_reader_kept_for_many_healthy_files_gives_each_its_own_cpu_budget(tmp_path):
    """The reader's child serves many files; the CPU limit that stops a looping HDF5 library is
    per file, so a long rebuild never reports healthy files as damaged (it did after about a
    second of CPU over all files: SIGXCPU, "the HDF5 library crashed reading it (exit -24)")."""
    import resource

    good = tmp_path / "good.h5"
    assert cli("run", str(short_protocol(tmp_path)), "--output", str(good), "--catalogue", "none").returncode == 0
    with BoundedReader(timeout_s=30.0, workers=1) as reader:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        found = list(reader.read_all([good] * 1500))
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    damaged = [why for _, facts, why in found if facts is None]
    assert not damaged, f"{len(damaged)} of 1500 reads of a healthy file refused: {damaged[:2]}"
    used = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    assert used > 3.0, f"the reads took {used:.2f} s of CPU: not enough to pass the old whole-life limit"
