"""``sim://`` through pyserial's serial_for_url."""

from __future__ import annotations

import time

import pytest
import serial
from simhost import HELLO

import tsa_bench.transport  # noqa: F401  (registers sim://)
from tsa_bench.bench.config import CONFIG_DIR
from tsa_bench.protocol import MessageDecoder, encode, msg
from tsa_bench.transport.protocol_sim import Serial, hand_over_bench, parse_sim_url

E = msg.EventKind


class PortHost:
    """Minimal host on a pyserial port: numbered commands, decoded replies."""

    def __init__(self, port) -> None:
        self.port = port
        self.seq = 0
        self.dec = MessageDecoder()

    def send(self, message) -> None:
        self.seq += 1
        self.port.write(encode(message, self.seq))

    def read(self) -> list:
        data = self.port.read(max(1, self.port.in_waiting))
        return [f.message for f in self.dec.feed(data)]

    def read_until(self, predicate, max_reads: int = 10_000, heartbeat_every: int | None = None) -> list:
        seen = []
        for i in range(max_reads):
            if heartbeat_every and i % heartbeat_every == 0:
                self.send(msg.Heartbeat())
            got = self.read()
            seen += got
            if any(predicate(m) for m in got):
                return seen
        raise AssertionError(f"not seen after {max_reads} reads: {seen[-3:]}")


def test_serial_for_url_gives_a_sim_port_that_boots():
    with serial.serial_for_url("sim://", timeout=0.1) as port:
        assert isinstance(port, Serial)
        host = PortHost(port)
        assert host.read_until(lambda m: isinstance(m, msg.Boot))[0].reason == msg.BootReason.POWER_ON
        host.send(HELLO)
        ident = host.read_until(lambda m: isinstance(m, msg.Identity))[-1]
        assert ident.flags & msg.DeviceFlags.SIMULATED and ident.steps_per_turn == 3200
        assert port.device is not None and port.device.now_s == 0.0


def test_url_parameters():
    bench = CONFIG_DIR / "sim.yaml"
    url = parse_sim_url(f"sim://?bench={bench}&speed=2.5&seed=42")
    assert (url.bench_path, url.speed, url.seed) == (str(bench), 2.5, 42)
    assert parse_sim_url("sim://?speed=0").speed is None
    assert parse_sim_url("sim://") == parse_sim_url("sim:///")
    port = serial.serial_for_url(f"sim://?bench={bench}&seed=3", timeout=0)
    assert port.device.bench.path == str(bench)
    port.close()


def test_a_handed_over_bench_is_used_while_its_file_is_unchanged(tmp_path):
    from tsa_bench.bench import load_bench

    path = tmp_path / "bench.yaml"
    text = (CONFIG_DIR / "sim.yaml").read_text()
    path.write_text(text)
    bench = load_bench(path)
    hand_over_bench(bench)
    with serial.serial_for_url(f"sim://?bench={path}", timeout=0) as port:
        assert port.device.bench.plant is bench.plant       # not loaded again
        assert port.device.bench.path == str(path)
    path.write_text(text.replace("name:", "name: changed", 1))   # the file changed since: loaded again
    with serial.serial_for_url(f"sim://?bench={path}", timeout=0) as port:
        assert port.device.bench.plant is not bench.plant
        assert port.device.bench.name.startswith("changed")


@pytest.mark.parametrize("url, complaint", [
    ("sim://?sped=2", "unknown parameter"),
    ("sim://?speed=fast", "speed"),
    ("sim://?speed=-1", "speed"),
    ("sim://?speed=inf", "speed"),
    ("sim://?seed=1.5", "seed"),
    ("sim://?seed=1&seed=2", "seed"),
    ("sim://somehost", "somehost"),
])
def test_bad_url_parameters_raise_value_error(url, complaint):
    with pytest.raises(ValueError, match=complaint):
        serial.serial_for_url(url)


def test_missing_bench_file_raises_value_error(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        serial.serial_for_url(f"sim://?bench={tmp_path / 'nope.yaml'}")


def test_read_advances_at_most_one_quantum_per_call():
    port = serial.serial_for_url("sim://", timeout=0.1)
    port.reset_input_buffer()
    assert port.read(100) == b""                      # idle, sampling off: nothing to say
    assert port.device.now_s == pytest.approx(0.25)   # min(watchdog 2 s / 8, 0.5)
    assert port.in_waiting == 0
    assert port.device.now_s == pytest.approx(0.5)


def test_heartbeating_every_quantum_survives_a_silent_dwell():
    """No sampling: the host sees nothing but its own replies. It heartbeats every other
    read: one read returns the heartbeat's replies, the next finds nothing buffered and
    runs the device one quantum (0.25 s)."""
    port = serial.serial_for_url("sim://", timeout=0.1)
    host = PortHost(port)
    host.send(msg.Dwell(0, 30_000_000))
    t0 = time.perf_counter()
    seen = host.read_until(lambda m: isinstance(m, msg.Event) and m.kind == E.QUEUE_EMPTY, heartbeat_every=2)
    assert time.perf_counter() - t0 < 2.0               # dwells cost no wall time at full speed
    assert not [m for m in seen if isinstance(m, msg.Event) and m.kind == E.FAULT]
    assert port.device.now_s == pytest.approx(30.0)


def test_silent_host_trips_the_watchdog_through_the_port():
    port = serial.serial_for_url("sim://", timeout=0.1)
    host = PortHost(port)
    host.send(msg.Dwell(0, 30_000_000))
    seen = host.read_until(lambda m: isinstance(m, msg.Event) and m.kind == E.FAULT)
    assert seen[-1].t_us == 2_000_000


def test_samples_and_a_move_through_the_port():
    port = serial.serial_for_url("sim://?seed=5", timeout=0.1)
    host = PortHost(port)
    host.send(msg.SetPosition(0))
    host.send(msg.SetSampling(0, 10_000))
    host.send(msg.MoveBy(1, 3200, 16_000, 320_000))
    seen = host.read_until(lambda m: isinstance(m, msg.Event) and m.kind == E.QUEUE_EMPTY and m.segment == 1,
                           heartbeat_every=20)
    got = [m for m in seen if isinstance(m, msg.Sample)]
    assert [s.counter for s in got] == list(range(len(got)))
    assert any(s.motor_moving for s in got)
    assert port.device.executor.position_steps == 3200


def test_speed_keeps_virtual_time_behind_wall_time():
    port = serial.serial_for_url("sim://?speed=10", timeout=0.05)
    host = PortHost(port)
    host.send(msg.SetSampling(0, 100_000))
    # Run until the device has lived 2 s (about 0.2 s of wall time on an idle machine);
    # the deadline is only for a hang, never the measurement.
    deadline = time.monotonic() + 120.0
    got = []
    while port.device.now_s < 2.0:
        assert time.monotonic() < deadline, "the simulated device stopped advancing"
        got += [m for m in host.read() if isinstance(m, msg.Sample)]
        assert port.device.now_s <= (time.monotonic() - port._pacer.t0_wall) * 10 + 1e-6
    got += [m for m in host.read() if isinstance(m, msg.Sample)]
    # 100 ms sampling: never more samples than the device has lived periods (+1 for the
    # first and the read that finished the loop).
    assert 2 <= len(got) <= port.device.now_s / 0.1 + 2


def test_closed_port_refuses_io():
    port = serial.serial_for_url("sim://")
    port.close()
    with pytest.raises(serial.PortNotOpenError):
        port.read(1)
    with pytest.raises(serial.PortNotOpenError):
        port.write(b"x")
