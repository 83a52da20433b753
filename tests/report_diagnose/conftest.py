"""Fixtures for the diagnose report/CLI tests (helpers in diagnose_helpers.py)."""

from __future__ import annotations

import pytest
from diagnose_helpers import build_result


@pytest.fixture
def result_with_cause():
    return build_result(verdict="named")


@pytest.fixture
def result_clean():
    return build_result(verdict="explained")
