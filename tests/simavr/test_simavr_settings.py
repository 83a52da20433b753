"""The simavr section of a bench file and the plant server, without the emulator."""

from __future__ import annotations

import dataclasses
import socket
import struct
import threading

import pytest
import yaml

from tsa_bench.bench import BenchConfigError, load_bench, parse_bench
from tsa_bench.sim.plant import plant_from_config
from tsa_bench.sim.sensors import SimSensors
from tsa_bench.bench.simavr_section import simavr_settings
from tsa_bench.simavr import PlantServer
from tsa_bench.simavr.plant_server import HELLO


def _bench_text(repo_root, simavr_section: str) -> str:
    text = (repo_root / "configs/bench/simavr.yaml").read_text()
    return text[:text.index("simavr:\n")] + simavr_section


def test_shipped_settings_resolve_the_firmware_dir(repo_root):
    s = simavr_settings(load_bench(repo_root / "configs/bench/simavr.yaml"))
    assert s.firmware_dir == repo_root / "firmware"
    assert s.elf == repo_root / "firmware/build/tsa_bench.elf" and s.harness.name == "tsa_simavr"
    assert s.heater_supply_V == 24.0 and s.lead_ms == 1000.0 and s.build is True


@pytest.mark.parametrize("section, message", [
    ("simavr: {speedy: 1}\n", "unknown key 'speedy'"),
    ("simavr: {lead_ms: -5}\n", "'lead_ms' must be a number in"),
    ("simavr: {heater_supply_V: yes}\n", "'heater_supply_V' must be a number"),
    ("simavr: {build: 1}\n", "'build' must be true or false"),
    ("simavr: {firmware_dir: 3}\n", "'firmware_dir' must be a path"),
])
def test_bad_settings_name_file_and_key(repo_root, tmp_path, section, message):
    path = tmp_path / "bench.yaml"
    path.write_text(_bench_text(repo_root, section))
    with pytest.raises(BenchConfigError) as err:  # the bench file is refused as a whole, before any use
        parse_bench(path.read_text(), str(path))
    assert str(path) in str(err.value) and message in str(err.value)
    good = parse_bench(_bench_text(repo_root, ""), str(path))
    section_only = dataclasses.replace(good, simavr=yaml.safe_load(section)["simavr"])
    with pytest.raises(BenchConfigError) as err:  # and the section on its own
        simavr_settings(section_only)
    assert str(path) in str(err.value) and message in str(err.value)


def test_firmware_dir_outside_the_project_needs_trust(repo_root, tmp_path):
    """The simavr bench runs `make` in firmware_dir: only this project's folder unless trusted."""
    path = tmp_path / "bench.yaml"
    path.write_text(_bench_text(repo_root, f"simavr: {{firmware_dir: {tmp_path}}}\n"))
    with pytest.raises(BenchConfigError, match="--trust-firmware-dir") as err:
        load_bench(path)
    assert str(path) in str(err.value) and str(tmp_path) in str(err.value)
    assert simavr_settings(load_bench(path, trust_firmware_dir=True), trust_firmware_dir=True).firmware_dir == tmp_path
    inside = tmp_path / "inside.yaml"  # a relative path to the project's own folder is fine
    inside.write_text(_bench_text(repo_root, f"simavr: {{firmware_dir: {repo_root / 'firmware'}}}\n"))
    assert simavr_settings(load_bench(inside)).firmware_dir == repo_root / "firmware"


def test_plant_server_answers_like_the_simulated_sensors(repo_root, tmp_path):
    bench = load_bench(repo_root / "configs/bench/simavr.yaml")
    server = PlantServer(bench, str(tmp_path / "p.sock"), heater_supply_V=24.0, seed=5)
    harness = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    t = threading.Thread(target=server.wait_connected, args=(5.0,))
    t.start()
    harness.connect(server.path)
    harness.sendall(HELLO)
    t.join()
    server.start()
    assert harness.recv(1) == b"G"
    reference = plant_from_config(bench.plant, seed=5)
    sensors = SimSensors(bench.position, bench.resistance)
    for kind, t_s, steps, duty in ((b"L", 0.5, 3200 * 10, 0.0), (b"R", 0.6, 3200 * 20, 0.0), (b"L", 1.0, 0, 0.25)):
        harness.sendall(struct.pack("<BBxxidd", kind[0], 0, steps, t_s, duty))
        counts, flags = struct.unpack("<iB3x", harness.recv(8))
        reading = reference.sample(t_s, steps / 3200, 24.0 * duty ** 0.5, False)
        expected = (sensors.position_raw(reading.length_mm), 0) if kind == b"L" else (
            sensors.resistance_raw(reading.resistance_ohm)[0], 0)
        assert (counts, flags) == expected
    harness.sendall(struct.pack("<BBxxidd", ord("X"), 0, 0, 2.0, 0.0))   # malformed: the server hangs up
    assert harness.recv(8) == b""
    assert "malformed plant request" in server.error
    server.close()
