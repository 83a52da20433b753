"""Shared test fixtures: paths into the repository."""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

import pytest
from hypothesis import settings

from tests.cpu_share import cpu_share

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return ROOT


# Property tests draw the same examples on every run: a suite result must not depend on
# which random inputs a run happened to draw. Wider random exploration is the job of
# scripts/fuzz_inputs.py, whose findings become fixed cases here.
settings.register_profile("deterministic", derandomize=True, print_blob=True)
settings.load_profile("deterministic")


# -- two workers (pytest-xdist, `-n 2 --dist loadgroup` in pyproject.toml) -----------------
# Each module runs whole on one worker (its module fixtures are made once). Modules that build
# or run the firmware share one group, so they run one after another on one worker: `make` in
# firmware/ from two processes at once would write the same object files. Their tests also run
# with the other worker paused (pytest_runtest_protocol below): the firmware keeps wall-clock time.
FIRMWARE_GROUP = "firmware"
_FIRMWARE_MARKS = re.compile(r'"make"|make_rig|firmware_dir|simavr|native_port|native_pty|tsa_native|fuzz-firmware'
                             r'|firmware/build|tests\.bluesky\.helpers|tests\.operator\.terminal|conformance_scenarios'
                             r'|\bnative\b')


def group_of(module: Path) -> str:
    """The xdist group of a test module: :data:`FIRMWARE_GROUP` when its text (or a test
    helper it names) builds or runs the firmware, else the module's own path."""
    return FIRMWARE_GROUP if _FIRMWARE_MARKS.search(module.read_text(encoding="utf-8")) else \
        module.relative_to(ROOT).as_posix()


def pytest_collection_modifyitems(config, items) -> None:
    groups: dict[Path, str] = {}
    for item in items:
        module = Path(str(item.fspath))
        if module not in groups:
            groups[module] = group_of(module)
        item.add_marker(pytest.mark.xdist_group(groups[module]))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """On two workers, a firmware module's test (its module fixtures' set-up and teardown
    included) runs with the other worker paused (tests/cpu_share.py)."""
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if run is None:
        yield
        return
    group = item.get_closest_marker("xdist_group")
    exclusive = group is not None and group.args[0] == FIRMWARE_GROUP
    with cpu_share(Path(tempfile.gettempdir()) / f"tsa-bench-tests-{run}", exclusive):
        yield
