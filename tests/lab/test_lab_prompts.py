"""A person at a lab of rigs: a real rig's questions come to the lab's one terminal naming
their rig, one at a time, and no other rig's output is written into an open question (it
waits and follows the answer). The lab in a pseudo-terminal, a scripted person typing, a
rehearsal rig that passes for hardware (`sim-serve --as-hardware`) beside a simulated rig."""

from __future__ import annotations

from pathlib import Path

from tests.catalogue.helpers import short_protocol, wait_for
from tests.operator.terminal import SimRig, Terminal
from tsa_bench.store import read_run
from tsa_bench.store.live import sidecar_path

PROMPT = "Hang 350 g on rig M then wait"
PROTOCOL = f"""name: at-the-rig
load_g: 200
sampling_period_s: 0.05
defaults: {{rate_turns_per_s: 3, accel_turns_per_s2: 30}}
steps:
  - move_to: {{turns: 4}}
  - prompt: {{text: "{PROMPT}", load_g: 350}}
  - hold: {{duration_s: 2}}
  - move_to: {{turns: 0}}
"""


def _closed(out: Path, rig: str) -> bool:
    """The rig's run file is written and closed (its live sidecar gone)."""
    found = sorted(out.glob(f"*_{rig}_*.h5"))
    return bool(found) and not sidecar_path(found[0]).exists()


def _status(out: Path, rig: str) -> str:
    """The rig's run file's exit status and reason, for a failure message."""
    found = sorted(out.glob(f"*_{rig}_*.h5"))
    if not found:
        return f"rig {rig}: no run file"
    run = read_run(found[0])
    return f"rig {rig}: {run.exit_status} ({run.attrs.get('reason', '')}), {len(run)} samples"


def test_questions_name_their_rig_and_no_other_rig_writes_into_them(tmp_path):
    short_protocol(tmp_path)
    (tmp_path / "at-the-rig.yaml").write_text(PROTOCOL)
    rig = SimRig()
    try:
        lab = tmp_path / "lab.yaml"
        lab.write_text("name: person-lab\nrigs:\n"
                       f"  - {{name: M, protocol: at-the-rig.yaml, bench: arduino-mega.yaml, port: {rig.path}}}\n"
                       # S runs in real time (about 50 s: the pacing never lets it run ahead of the
                       # wall clock), so it is still running when M's question comes on a busy machine
                       "  - {name: S, protocol: short-life.yaml, bench: sim, speed: 1, seed: 1}\n")
        out = tmp_path / "runs"
        t = Terminal(["lab", str(lab), "--out", str(out)], 200, 50, tmp_path)
        t.wait_raw("[y/N]")
        asked = len(t.raw)
        assert b">>> [M] The device does not know the motor's position" in t.raw and b"Is the TSA untwisted now" in t.raw
        assert not _closed(out, "S"), ("rig S ended before the question: nothing could have been written into it\n"
                                       + _status(out, "S") + "\n" + t.output()[-3000:])
        wait_for(lambda: _closed(out, "S"), "rig S to end while rig M's question is open", 300)
        t._pump(0.5)
        assert b"[S]" not in t.raw[asked:], t.output()[asked - 200:]   # S's end waits behind the question
        t.type("y\r")
        t.wait_raw("Press Enter when done")
        assert f">>> [M] {PROMPT} (load now 350 g)".encode() in t.raw
        rig.hang(350)
        t.type("\r")
        assert t.finish() == 0, t.output()[-3000:]
        assert b"[S] -- finished (exit 0)" in t.raw[asked:]   # ...and follows the answer
        assert "2 of 2 rigs succeeded" in t.output() and "Traceback" not in t.output()
    finally:
        rig.close()
