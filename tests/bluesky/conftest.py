"""Fixtures of the Bluesky tests."""

from __future__ import annotations

import pytest

from tests.bluesky.helpers import connect, make_re


@pytest.fixture
def session():
    """(RunEngine, its documents, a rig on sim://): the RunEngine first, its loop runs the device."""
    re, rec = make_re()
    rig = connect("sim://?seed=3")
    yield re, rec, rig
    rig.close()
