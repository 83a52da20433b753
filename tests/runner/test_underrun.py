"""Which QUEUE_EMPTY is an underrun (runner/underrun.py), command by command."""

from __future__ import annotations

from tsa_bench.runner.underrun import Bursts


def test_only_the_last_command_of_a_burst_can_run_dry():
    b = Bursts()
    for seg in (0, 1, 2):          # one burst: an instant segment 0 may finish before 1 arrives
        b.accepted(seg)
    b.end(oldest=0)
    b.accepted(3)                  # a later burst: a long hold of two DWELLs, then segment 4
    b.accepted(3)
    b.end(oldest=1)
    b.accepted(4)
    b.end(oldest=2)
    assert not b.ran_dry_after(0, 1)      # the ACK round trip within a burst
    assert not b.ran_dry_after(2, 0)      # not a command that was sent
    assert b.ran_dry_after(2, 1)          # the host was not there to send segment 3
    assert not b.ran_dry_after(3, 1)      # the first DWELL of 3: its second came with it
    assert b.ran_dry_after(3, 2)
    assert not b.ran_dry_after(3, 2)      # each once
    assert b.ran_dry_after(4, 1)


def test_burst_ends_the_device_has_passed_are_forgotten():
    """A run that never runs dry (a lifetime run, 100,000s of bursts) keeps a few."""
    b = Bursts()
    for seg in range(200_000):
        b.accepted(seg)
        b.end(oldest=max(0, seg - 16))
    assert len(b._ends) <= 20
    assert b.ran_dry_after(199_999, 1)
