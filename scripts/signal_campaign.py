#!/usr/bin/env python3
"""Signal campaign: Ctrl-C / SIGTERM at random moments of runs, counted.

Runs N flush-time trials (a run in this process whose writer signals itself in the
middle of a flush, sometimes twice, sometimes again while the file closes) and N
double-interrupt trials (`tsa-bench run` over a real serial link, two signals a few
milliseconds apart at a random moment), then prints, per kind: trials, STOP sent,
file readable and "aborted", and the outcomes (run status, or exit code). Exit code 0
when every trial sent STOP, left a readable "aborted" file and (CLI) exited 130.

    PYTHONPATH=host python3 scripts/signal_campaign.py [--trials 50] [--seed 0]
"""

from __future__ import annotations

import argparse
import random
import sys
import tempfile
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.faults.signal_trials import cli_double_interrupt_trial, flush_trial  # noqa: E402
from tests.runner.test_reliability import SHORT  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rng = random.Random(args.seed)
    good = True
    for kind, trial, expected in (("flush-time", lambda d: flush_trial(d, rng, SHORT), "aborted"),
                                  ("double Ctrl-C (CLI)", lambda d: cli_double_interrupt_trial(d, rng), "exit 130")):
        outcomes: Counter[str] = Counter()
        stops = readable = 0
        failures = []
        for i in range(args.trials):
            with tempfile.TemporaryDirectory() as d:
                r = trial(Path(d))
            outcomes[r.outcome] += 1
            stops += r.stop_sent
            readable += r.readable
            if r.outcome != expected or not (r.stop_sent and r.readable):
                failures.append(f"  trial {i}: {r.outcome}, stop {r.stop_sent}, readable {r.readable}: {r.detail}")
        good &= not failures
        print(f"{kind:<20} trials {args.trials}  STOP sent {stops}  file readable and aborted {readable}  "
              f"outcomes {dict(outcomes)}")
        print("\n".join(failures[:10]))
    return 0 if good else 1


if __name__ == "__main__":
    sys.exit(main())
