"""What to do when a program or server the suite needs is not there.

On a developer's machine the tests that need it are skipped with the reason (and what
installs it). Where the suite must be whole, they fail instead: on CI (``CI`` set to a true
value, as CI runners do) or with ``TSA_BENCH_REQUIRE_SERVICES=1``, which .ci/run sets after
scripts/setup-test-services.sh has installed Debian's chromium and started PostgreSQL, so
a broken install step shows as red tests, never as a quiet skip.
"""

from __future__ import annotations

import os

import pytest


def required() -> bool:
    """True where a missing service is a failure rather than a skip (module contract)."""
    ci = os.environ.get("CI", "").strip().lower()
    return os.environ.get("TSA_BENCH_REQUIRE_SERVICES") == "1" or ci not in ("", "0", "false", "no")


def unavailable(reason: str) -> None:
    """Skip the calling test with ``reason``, or fail it where services are required."""
    if required():
        pytest.fail(f"{reason} (required here: CI or TSA_BENCH_REQUIRE_SERVICES=1)", pytrace=False)
    pytest.skip(reason)
