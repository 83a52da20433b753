"""Held-out means held out: the declared held-out records never reach the calibration.

The calibration pipeline (the one scripts/calibrate_presets.py runs: load the records and the
plan with its held-out file, keep the fits' records, fit -- an extension chosen by
cross-validation -- and write the presets) is run twice on a small plan of the real records,
once with held-out records changed in their files. The written presets must be bit-identical,
and no held-out record may be computed while fitting or choosing the extension.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from tsa_bench.reproduce import calibrate as cal
from tsa_bench.reproduce.experiments import BENCH_DIR
from tsa_bench.reproduce.manipulator import CONFIG as MANIPULATOR_FILE
from tsa_bench.reproduce.plan import HELD_OUT_FILE, PLAN_FILE, load_plan
from tsa_bench.reproduce.records import RECORDS_DIR, RecordsError, load_records, record_files

FITTED = ["t3.1.3ply.twist.100g.p0", "t3.1.3ply.twist.100g.p1"]
SMALL_PLAN = f"""
fits:
  - name: small
    parameters:
      sim-3ply:radius_mm: [0.15, 0.7]
      sim-3ply:effects.twist_stiffening.per_turn: [0, 0.006]
    records: [{", ".join(FITTED)}]
    extension:
      effect: twist_stiffening
      parameters: [sim-3ply:effects.twist_stiffening.per_turn]
"""
#: held-out records changed in their files: (file, pattern, replacement)
CHANGES = [("ch3-actuation-models.yaml", r"(id: t3\.1\.3ply\.twist\.150g\.p1, [^}]*?value: )-0\.024", r"\g<1>5.5"),
           ("ch3-actuation-models.yaml", r"(id: t3\.1\.3ply\.twist\.200g\.p2, [^}]*?value: )\S+?,", r"\g<1>-3.0,"),
           ("ch2-characterisation.yaml", r"(id: ch2\.strain\.3ply_avg_active\n(?:.*\n)*?    value: )29\.10", r"\g<1>99")]


def _records_dir(tmp: Path, change: bool) -> Path:
    d = tmp / ("changed" if change else "as-shipped")
    d.mkdir()
    for f in record_files():
        text = f.read_text(encoding="utf-8")
        for name, pattern, repl in CHANGES if change else []:
            if f.name == name:
                text, n = re.subn(pattern, repl, text, count=1)
                assert n == 1, (name, pattern)
        (d / f.name).write_text(text, encoding="utf-8")
    (d / "calibration.yaml").write_text(SMALL_PLAN, encoding="utf-8")
    records = load_records(record_files(d))
    held = [r.id for r in records if r.measure is not None and r.id not in FITTED]
    (d / "held-out.yaml").write_text("held_out:\n" + "".join(f"  - {rid}\n" for rid in held), encoding="utf-8")
    return d


def _calibrate(records_dir: Path, out: Path, read: list[str]) -> dict[str, bytes]:
    records = load_records(record_files(records_dir))
    plan = load_plan(records, records_dir / "calibration.yaml")
    settings = cal.load_settings()
    new, _, ext = cal.calibrate(plan, cal.calibration_records(records, plan), settings, seed=100, maxfev=6, passes=1)
    assert [e.effect for e in ext] == ["twist_stiffening"] and ext[0].records == FITTED
    out.mkdir()
    for p in BENCH_DIR.glob("*.yaml"):
        shutil.copy(p, out / p.name)
    shutil.copy(MANIPULATOR_FILE, out / "manipulator.yaml")
    cal.write_calibration(new, plan, bench_dir=out, manipulator_file=out / "manipulator.yaml")
    return {p.name: p.read_bytes() for p in sorted(out.glob("*.yaml"))}


def test_changed_held_out_records_leave_the_calibrated_presets_bit_identical(tmp_path, monkeypatch):
    read: list[str] = []
    real = cal.simulated_values

    def spy(records, lab):
        read.extend(r.id for r in records)
        return real(records, lab)
    monkeypatch.setattr(cal, "simulated_values", spy)
    shipped = _records_dir(tmp_path, change=False)
    changed = _records_dir(tmp_path, change=True)
    by_id = {r.id: r for r in load_records(record_files(changed))}
    assert by_id["t3.1.3ply.twist.150g.p1"].value == 5.5 and by_id["ch2.strain.3ply_avg_active"].value == 99
    a = _calibrate(shipped, tmp_path / "a", read)
    b = _calibrate(changed, tmp_path / "b", read)
    assert a == b
    assert a["sim-3ply.yaml"] != (BENCH_DIR / "sim-3ply.yaml").read_bytes()   # the fit did write something
    assert read and set(read) <= set(FITTED), sorted(set(read) - set(FITTED))


def test_the_calibration_refuses_held_out_records():
    records = load_records()
    plan = load_plan(records)
    held = [r for r in records if r.id in plan.held_out][:1]
    with pytest.raises(cal.HeldOutError, match=held[0].id.replace(".", r"\.")):
        cal.calibrate(plan, cal.calibration_records(records, plan) + held, cal.load_settings(), maxfev=5,
                      only=["no fit"])
    assert not {r.id for r in cal.calibration_records(records, plan)} & plan.held_out


def test_a_fit_naming_a_held_out_record_is_refused_with_its_place(tmp_path):
    records = load_records()
    plan_text = PLAN_FILE.read_text(encoding="utf-8")
    held_text = HELD_OUT_FILE.read_text(encoding="utf-8")
    (tmp_path / "calibration.yaml").write_text(plan_text, encoding="utf-8")
    (tmp_path / "held-out.yaml").write_text(held_text + "  - ch4.control.rise_time\n", encoding="utf-8")
    with pytest.raises(RecordsError) as exc:
        load_plan(records, tmp_path / "calibration.yaml")
    line = next(i for i, ln in enumerate(plan_text.splitlines(), 1) if ln.strip() == "- ch4.control.rise_time")
    assert f"calibration.yaml:{line}:" in str(exc.value) and "declared held out (held-out.yaml:" in str(exc.value)


def test_every_simulated_record_is_declared(tmp_path):
    records = load_records()
    (tmp_path / "calibration.yaml").write_text(PLAN_FILE.read_text(encoding="utf-8"), encoding="utf-8")
    text = HELD_OUT_FILE.read_text(encoding="utf-8").replace("  - ch2.scheme1.range\n", "")
    (tmp_path / "held-out.yaml").write_text(text, encoding="utf-8")
    with pytest.raises(RecordsError, match=r"ch2-characterisation\.yaml:\d+:\d+: ch2\.scheme1\.range: a simulated record "
                                           r"neither built-from, fitted nor declared held out"):
        load_plan(records, tmp_path / "calibration.yaml")
    plan = load_plan(records)
    roles = {plan.role(r.id) for r in records if r.measure is not None}
    assert roles == {"built-from", "fitted", "held-out"}
    assert all(plan.role(rid) == "held-out" for rid in plan.held_out) and RECORDS_DIR == HELD_OUT_FILE.parent
