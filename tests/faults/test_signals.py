"""Ctrl-C and SIGTERM at random moments, including in the middle of a file flush and
twice in a row: STOP always goes out, the file always reads back whole and says
"aborted", `run` exits 130. (scripts/signal_campaign.py runs 50 + 50 of these.)"""

from __future__ import annotations

import random
import sys

import pytest

from tests.faults.signal_trials import cli_double_interrupt_trial, flush_trial
from tests.runner.test_reliability import SHORT

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")


@pytest.mark.parametrize("seed", range(6))
def test_a_signal_during_a_flush_stops_the_run_and_keeps_whole_rows(tmp_path, seed):
    result = flush_trial(tmp_path, random.Random(seed), SHORT)
    assert result.outcome == "aborted", result.detail
    assert result.stop_sent and result.readable, result.detail


@pytest.mark.parametrize("seed", range(2))
def test_double_ctrl_c_on_tsa_bench_run_sends_stop_and_exits_130(tmp_path, seed):
    result = cli_double_interrupt_trial(tmp_path, random.Random(100 + seed))
    assert result.outcome == "exit 130", result.detail
    assert result.stop_sent and result.readable, result.detail
