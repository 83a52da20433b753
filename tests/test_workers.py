"""The suite runs on two pytest-xdist workers (pyproject.toml): every test module that
builds the firmware must be in the one firmware group (tests/conftest.py), so no two
`make` runs in firmware/ write the same object files at once.

What builds is found here from the code, not from the grouping's own text patterns: a
module, a conftest above it or a test helper it imports (transitively) calls a program
list that starts with ``make`` or the firmware fuzz script, or starts the simavr bench
(whose launcher runs ``make harness``)."""

from __future__ import annotations

import ast
from functools import cache
from pathlib import Path

from tests.conftest import FIRMWARE_GROUP, ROOT, group_of

SIMAVR_STARTS = ("SimavrBench", "simavr.yaml", "--mega")


def _tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"), str(path))


def _calls_make(tree: ast.Module) -> bool:
    for node in ast.walk(tree):
        if isinstance(node, (ast.List, ast.Tuple)) and node.elts:
            first = node.elts[0]
            if isinstance(first, ast.Constant) and first.value in ("make", "scripts/fuzz-firmware.sh"):
                return True
            if isinstance(first, ast.Constant) and first.value == "bash" and len(node.elts) > 1 \
                    and isinstance(node.elts[1], ast.Constant) and "fuzz-firmware" in str(node.elts[1].value):
                return True
        if isinstance(node, ast.Constant) and isinstance(node.value, str) \
                and any(s in node.value for s in SIMAVR_STARTS):
            return True
        if isinstance(node, ast.Name) and node.id in SIMAVR_STARTS:
            return True
    return False


def _helpers(tree: ast.Module) -> list[Path]:
    """The test helper modules (tests/...) a module imports."""
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("tests"):
            names.append(node.module)
            names += [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names += [a.name for a in node.names if a.name.startswith("tests")]
    paths = [ROOT / (n.replace(".", "/") + ".py") for n in names]
    return [p for p in paths if p.is_file()]


@cache
def _builds(path: Path) -> bool:
    tree = _tree(path)
    return _calls_make(tree) or any(_builds(h) for h in _helpers(tree) if h != path)


def _conftests(module: Path) -> list[Path]:
    return [d / "conftest.py" for d in module.parents if d.is_relative_to(ROOT / "tests")
            and (d / "conftest.py").is_file()]


def test_every_module_that_builds_the_firmware_is_in_the_firmware_group():
    modules = sorted((ROOT / "tests").rglob("test_*.py"))
    building = [m for m in modules if _builds(m) or any(_builds(c) for c in _conftests(m))]
    assert len(building) >= 20   # simavr, firmware, native-firmware rigs, flashing, bluesky on the firmware
    outside = [m.relative_to(ROOT).as_posix() for m in building if group_of(m) != FIRMWARE_GROUP]
    assert not outside, f"these modules build the firmware outside the firmware group: {outside}"


def test_other_modules_run_whole_on_one_worker():
    module = ROOT / "tests" / "store" / "test_kill_anywhere.py"
    assert not _builds(module) and group_of(module) == "tests/store/test_kill_anywhere.py"


def _turnstile_taken(folder: Path) -> bool:
    """Someone holds the turnstile (a firmware test waiting for the others to finish)."""
    import fcntl
    with open(folder / "turnstile.lock", "a+") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        fcntl.flock(f, fcntl.LOCK_UN)
        return False


def test_a_firmware_test_runs_alone_and_a_waiting_one_is_not_starved(tmp_path):
    import threading

    from tests.catalogue.helpers import wait_for
    from tests.cpu_share import cpu_share

    entered: list[str] = []
    release = {k: threading.Event() for k in "AEB"}

    def hold(name: str, exclusive: bool) -> None:
        with cpu_share(tmp_path, exclusive):
            entered.append(name)
            release[name].wait(60)

    threads = {"A": threading.Thread(target=hold, args=("A", False)),
               "E": threading.Thread(target=hold, args=("E", True)),
               "B": threading.Thread(target=hold, args=("B", False))}
    threads["A"].start()
    wait_for(lambda: entered == ["A"], "an ordinary test to start", 30)
    threads["E"].start()
    wait_for(lambda: _turnstile_taken(tmp_path), "the firmware test to wait at the turnstile", 30)
    assert entered == ["A"]                 # not beside an ordinary test
    threads["B"].start()                    # an ordinary test arriving while the firmware one waits...
    release["A"].set()
    wait_for(lambda: "E" in entered, "the firmware test to start once the ordinary one ended", 30)
    assert entered == ["A", "E"]            # ...waits behind it
    release["E"].set()
    wait_for(lambda: "B" in entered, "the next ordinary test to start", 30)
    release["B"].set()
    for t in threads.values():
        t.join(30)
    assert entered == ["A", "E", "B"]


def test_ordinary_tests_share(tmp_path):
    import threading

    from tests.cpu_share import cpu_share

    inside = threading.Event()

    def second() -> None:
        with cpu_share(tmp_path, False):
            inside.set()

    with cpu_share(tmp_path, False):
        t = threading.Thread(target=second, daemon=True)
        t.start()
        assert inside.wait(30), "a second ordinary test could not start beside the first"
    t.join(30)


def test_on_two_workers_a_firmware_module_holds_the_lock_alone():
    """This module is in the firmware group (it names `make`); on two workers (the README's
    command) its tests run while the lock is held exclusively: a shared taker is refused."""
    import fcntl
    import os
    import tempfile

    assert group_of(Path(__file__)) == FIRMWARE_GROUP
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if run is None:
        return   # `-n 0`: one process, nothing to share
    with open(Path(tempfile.gettempdir()) / f"tsa-bench-tests-{run}" / "cpu.lock", "a+") as cpu:
        try:
            fcntl.flock(cpu, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return
        fcntl.flock(cpu, fcntl.LOCK_UN)
    raise AssertionError("a firmware test ran without holding the lock alone")
