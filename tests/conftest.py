"""Shared test fixtures: paths into the repository."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import settings

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return ROOT


# Property tests draw the same examples on every run: a suite result must not depend on
# which random inputs a run happened to draw. Wider random exploration is the job of
# scripts/fuzz_inputs.py, whose findings become fixed cases here.
settings.register_profile("deterministic", derandomize=True, print_blob=True)
settings.load_profile("deterministic")
