"""Calibration fits, the calibrated bench file (comments kept, records appended and
checked), offline `calibrate --points`, and how `ports` recognises a Mega."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from tsa_bench.bench import BenchConfigError, load_bench, parse_bench
from tsa_bench.cli import main
from tsa_bench.rig.benchfile import BenchWriteError, calibrated_text, write_new_bench
from tsa_bench.rig.calibration import CalibrationError, fit_position, fit_resistance
from tsa_bench.rig.ports import PortInfo, likely_board

ROOT = Path(__file__).resolve().parents[2]
MEGA = ROOT / "configs" / "bench" / "arduino-mega.yaml"


def test_fits_recover_a_known_line_and_report_residuals():
    counts = [10000.0, 12000.0, 15000.0, 18000.0]
    true = [121.875 + 0.0105 * c for c in counts]
    noisy = [v + e for v, e in zip(true, (0.02, -0.01, 0.0, -0.01))]
    fit = fit_position(counts, noisy)
    assert fit.result["mm_per_count"] == pytest.approx(0.0105, rel=1e-3)
    assert fit.result["offset_mm"] == pytest.approx(121.875, abs=0.1)
    assert np.allclose(np.array(fit.reference) - np.array(fit.fitted), fit.residuals)
    assert fit.rms_residual == pytest.approx(np.sqrt(np.mean(np.square(fit.residuals))))
    ohm_per_count = 2.5 / 2**19 / 0.05
    r = fit_resistance([40000, 60000], [0.02 + 1.01 * ohm_per_count * 40000, 0.02 + 1.01 * ohm_per_count * 60000],
                       ohm_per_count)
    assert r.result["gain"] == pytest.approx(1.01) and r.result["offset_ohm"] == pytest.approx(0.02)


@pytest.mark.parametrize("counts,refs,error,part", [
    ([100.0], [1.0], 0.0, "two or more points"),
    ([100.0, 100.5], [1.0, 2.0], 0.0, "hardly change"),
    ([100.0, 110.0], [1.0, 2.0], 5.0, "less than 50.0 apart given the sensor's noise"),
    ([100.0, 200.0], [1.0, float("nan")], 0.0, "not a finite number"),
    ([100.0, 200.0], [1e9, -1e9], 0.0, "outside 1e-9..1e3"),
])
def test_fits_refuse_points_that_make_no_calibration(counts, refs, error, part):
    with pytest.raises(CalibrationError) as err:
        fit_position(counts, refs, error)
    assert part in str(err.value)


def _record(quantity="position"):
    if quantity == "position":
        return {"quantity": "position", "date": "2025-03-01T10:12:00+01:00",
                "points": [{"counts": 1.0, "length_mm": 2.0}, {"counts": 3.0, "length_mm": 4.0}],
                "result": {"mm_per_count": 1.0, "offset_mm": 1.0}, "rms_residual_mm": 0.0}
    return {"quantity": "resistance", "date": "2025-03-02T10:12:00+01:00",
            "points": [{"counts": 1.0, "resistance_ohm": 2.0}, {"counts": 3.0, "resistance_ohm": 4.0}],
            "result": {"gain": 1.02, "offset_ohm": -0.01}}


def test_the_calibrated_bench_keeps_everything_else(tmp_path):
    text = MEGA.read_text()
    once = calibrated_text(text, str(MEGA), "position", {"mm_per_count": 0.0111, "offset_mm": 100.5}, _record())
    twice = calibrated_text(once, "x.yaml", "resistance", {"gain": 1.02, "offset_ohm": -0.01}, _record("resistance"))
    bench = parse_bench(twice, "x.yaml")
    assert bench.position.mm_per_count == 0.0111 and bench.position.offset_mm == 100.5
    assert bench.resistance.gain == 1.02 and bench.resistance.offset_ohm == -0.01
    assert bench.resistance.resistance_ohm(1000) == pytest.approx(-0.01 + 1.02 * bench.resistance.ohm_per_count * 1000)
    for line in text.splitlines():   # every comment and every other value is still there
        if "mm_per_count" not in line and "offset_mm" not in line:
            assert line in twice, line
    assert twice.count("- quantity:") == 2 and twice.index("quantity: position") < twice.index("quantity: resistance")
    out = write_new_bench(text, str(MEGA), tmp_path / "mine.yaml", "position",
                          {"mm_per_count": 0.0111, "offset_mm": 100.5}, _record())
    assert load_bench(out).position.mm_per_count == 0.0111
    with pytest.raises(BenchWriteError, match="already exists"):
        write_new_bench(text, str(MEGA), out, "position", {"mm_per_count": 0.0111, "offset_mm": 100.5}, _record())
    flow = text + "calibrations: []\n"
    with pytest.raises(BenchWriteError, match="block list"):
        calibrated_text(flow, "f.yaml", "position", {"mm_per_count": 0.0111, "offset_mm": 100.5}, _record())


@pytest.mark.parametrize("records,part", [
    ("calibrations: {a: 1}", "calibrations: must be a list"),
    ("calibrations:\n  - {quantity: torque, date: '2025-01-01', points: [], result: {}}", "calibrations[0].quantity"),
    ("calibrations:\n  - quantity: position\n    date: yesterday\n    points: []\n    result: {}",
     "b.yaml:{+3}:11: calibrations[0].date: must be an ISO 8601"),
    ("calibrations:\n  - quantity: position\n    date: '2025-01-01'\n    points: [{counts: 1, length_mm: 2}]\n"
     "    result: {mm_per_count: 1, offset_mm: 0}", "points: must be a list of 2"),
    ("calibrations:\n  - quantity: position\n    date: '2025-01-01'\n"
     "    points: [{counts: 1, length_mm: 2}, {counts: x, length_mm: 3}]\n    result: {mm_per_count: 1, offset_mm: 0}",
     "calibrations[0].points[1].counts: must be a finite number"),
    ("calibrations:\n  - quantity: position\n    date: '2025-01-01'\n    colour: red\n", "calibrations[0].colour: unknown"),
])
def test_records_in_a_bench_file_are_checked_with_positions(records, part):
    base = MEGA.read_text()
    part = part.replace("{+3}", str(len(base.splitlines()) + 3))  # the record's third line
    with pytest.raises(BenchConfigError) as err:
        parse_bench(base + records + "\n", "b.yaml")
    assert part in str(err.value) and str(err.value).startswith("b.yaml:")


def test_calibrate_points_offline(tmp_path):
    out = tmp_path / "cal.yaml"
    res = CliRunner().invoke(main, ["calibrate", "position", "--bench", str(MEGA), "--points",
                                    "10000=226.9,12000=248.0,15000=279.4", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "rms residual" in res.output and "mm_per_count = 0.010" in res.output
    assert load_bench(out).position.mm_per_count == pytest.approx(0.010503, rel=1e-3)
    res = CliRunner().invoke(main, ["calibrate", "position", "--points", "10000:226", "--out", str(tmp_path / "y")])
    assert res.exit_code == 2 and "is not COUNTS=MM" in res.output


def test_ports_recognise_megas_and_their_clones():
    assert likely_board(PortInfo("/dev/ttyACM0", "", 0x2341, 0x0042))[0] == 2
    assert likely_board(PortInfo("/dev/ttyUSB0", "USB Serial", 0x1A86, 0x7523)) == (
        1, "CH340 USB-serial (common on Mega clones)")
    assert likely_board(PortInfo("COM7", "Arduino Mega 2560 (COM7)"))[0] == 2
    assert likely_board(PortInfo("/dev/ttyS0", "n/a"))[0] == 0


def test_a_slow_person_reading_the_ruler_trips_no_watchdog():
    """Issue 35: the device samples only while a point is measured, so a person taking
    three watchdog periods to read the ruler finds the rig as they left it (sampling on
    during the question tripped the watchdog: the next move was refused)."""
    from tsa_bench.rig.calibration import acquire
    from tsa_bench.rig.link import open_link

    bench = load_bench(ROOT / "configs" / "bench" / "sim.yaml")
    readings = iter(["300", "290", "280"])
    with open_link("sim://?seed=2", bench) as link:
        link.set_position(0)
        port = link.client.port
        device = port.device

        def slow_person(question: str) -> str:
            end = device.now_s + 3 * device.limits.watchdog_s
            while device.now_s < end:   # the rig's time runs on (sim:// advances on reads); the host is silent
                port.read(4096)
            return next(readings)

        counts, refs, _ = acquire(link, "position", slow_person, at_turns=[0, 5, 10], seconds=0.3, say=lambda _: None)
        assert device.fault == 0
    assert refs == [300.0, 290.0, 280.0] and len(set(counts)) == 3


def test_a_probe_that_stalls_is_one_line_not_a_traceback(monkeypatch):
    """`ports --probe`: a device that answers the handshake and then falls silent (no ACK)
    is reported on its line; the next port is still probed (issue 35, defect 4)."""
    from contextlib import contextmanager

    import tsa_bench.rig.link as link_module
    from tsa_bench.device import NoAcknowledgement
    from tsa_bench.rig.ports import probe

    @contextmanager
    def stalls(port, bench, boot_timeout_s=None):
        raise NoAcknowledgement("no ACK for HEARTBEAT after 10 transmissions over 2.55 s")
        yield

    monkeypatch.setattr(link_module, "open_link", stalls)
    result = probe("/dev/ttyACM9", load_bench(MEGA))
    assert not result.ok and "no ACK for HEARTBEAT" in result.text
