"""A person at a lab of rigs: a real rig's questions come to the lab's one terminal naming
their rig, one at a time, and no other rig's output is written into an open question (it
waits and follows the answer). The lab in a pseudo-terminal, a scripted person typing, a
rehearsal rig that passes for hardware (`sim-serve --as-hardware`) beside a simulated rig
on a relayed pty whose link the test cuts while the question is open, so that rig's end
(its failure and its last lines) falls inside the question whatever the machine's speed."""

from __future__ import annotations

from pathlib import Path

from tests.catalogue.helpers import wait_for
from tests.faults.ptybench import quick_bench, relayed_sim
from tests.operator.terminal import SimRig, Terminal
from tsa_bench.store import read_run
from tsa_bench.store.live import LiveTail, sidecar_path

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
#: Rig S's run: it would hold for 10 minutes in real time; it ends when the test cuts its link.
LONG_HOLD = """name: long-hold
load_g: 200
sampling_period_s: 0.1
steps:
  - hold: {duration_s: 600}
"""


def _recording(out: Path, rig: str) -> Path | None:
    """The rig's live sidecar while its run records (None before it starts and after it ends)."""
    found = sorted(out.glob(f"*_{rig}_*.h5.live"))
    return found[0] if found else None


def _ended(pid: int) -> bool:
    """The process has exited (gone, or a zombie its parent has not reaped yet)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] in "ZX"
    except FileNotFoundError:
        return True


def test_questions_name_their_rig_and_no_other_rig_writes_into_them(tmp_path):
    (tmp_path / "at-the-rig.yaml").write_text(PROTOCOL)
    (tmp_path / "long-hold.yaml").write_text(LONG_HOLD)
    rig = SimRig()
    try:
        with relayed_sim(quick_bench(tmp_path), speed=1.0) as relay:
            lab = tmp_path / "lab.yaml"
            lab.write_text("name: person-lab\nrigs:\n"
                           f"  - {{name: M, protocol: at-the-rig.yaml, bench: arduino-mega.yaml, port: {rig.path}}}\n"
                           f"  - {{name: S, protocol: long-hold.yaml, bench: pty-bench.yaml, port: {relay.path}}}\n")
            out = tmp_path / "runs"
            t = Terminal(["lab", str(lab), "--out", str(out)], 200, 50, tmp_path)
            t.wait_raw("[y/N]")
            asked = len(t.raw)
            assert b">>> [M] The device does not know the motor's position" in t.raw and b"Is the TSA untwisted now" in t.raw
            side = wait_for(lambda: _recording(out, "S"), "rig S to record while rig M's question is open")
            pid = LiveTail(side).header["pid"]
            relay.link.faults.cut_at_s = relay.link.now_s()   # S's cable pulled: its run fails and ends
            wait_for(lambda: _ended(pid), "rig S's run to end after its link was cut", 300)
            assert not sidecar_path(side.with_suffix("")).exists()
            t._pump(0.5)
            assert b"[S]" not in t.raw[asked:], t.output()[asked - 200:]   # S's end waits behind the question
            t.type("y\r")
            t.wait_raw("Press Enter when done")
            assert f">>> [M] {PROMPT} (load now 350 g)".encode() in t.raw
            rig.hang(350)
            t.type("\r")
            assert t.finish() == 1, t.output()[-3000:]   # one rig failed
        after = t.output()[len(t.raw[:asked].decode(errors="replace")):]
        assert "[S] -- finished (exit 1)" in after, after[-3000:]   # ...and follows the answer
        assert "1 of 2 rigs succeeded" in t.output() and "Traceback" not in t.output()
        s = read_run(side.with_suffix(""))
        assert s.exit_status == "failed", (s.exit_status, s.attrs.get("reason"))   # (samples or not: cut mid-run)
    finally:
        rig.close()
