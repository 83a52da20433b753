"""The simulated plant served to the simavr harness (firmware/sim/plant_link.h).

Units: device time in s, heater duty 0..1 (equivalent DC voltage = supply x sqrt(duty)),
load in g; answers in raw ADC counts.

Contract: one plant, one source of truth: the same :class:`~tsa_bench.sim.plant.TsaPlant`
and :class:`~tsa_bench.sim.sensors.SimSensors` as the Python simulated bench, built from
the bench file's ``plant`` mapping. :class:`PlantServer` listens on a Unix socket,
accepts the harness's connection (``wait_connected``), releases the AVR from reset
when the host calls :meth:`start`, then answers each query in a background thread:
'L' with the ADS1115 counts of the position sensor, 'R' with the CS5513 counts of the
string resistance and the overrange flag. :meth:`set_load_g` changes the hanging load
(thread-safe), as an operator does between steps. A malformed request or a lost
connection ends the thread and is kept in :attr:`error`; the harness then stops.
"""

from __future__ import annotations

import math
import os
import socket
import struct
import threading

from tsa_bench.benchdata import BenchConfig
from tsa_bench.sim.plant import plant_from_config
from tsa_bench.sim.sensors import SimSensors

__all__ = ["PlantServer", "HELLO"]

HELLO = b"TSAPLNT1"
_REQUEST = struct.Struct("<BBxxidd")
_REPLY = struct.Struct("<iB3x")


class PlantServer:
    """Serves plant readings to one harness over the Unix socket at ``path``."""

    def __init__(self, bench: BenchConfig, path: str, heater_supply_V: float, seed: int | None = None) -> None:
        self.path = path
        self.heater_supply_V = heater_supply_V
        self.plant = plant_from_config(bench.plant, seed=seed)
        self.sensors = SimSensors(bench.position, bench.resistance)
        self.steps_per_turn = bench.steps_per_turn
        self.queries = 0
        self.error: str | None = None
        self._lock = threading.Lock()
        self._conn: socket.socket | None = None
        self._thread: threading.Thread | None = None
        if os.path.exists(path):
            os.unlink(path)
        self._listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._listener.bind(path)
        self._listener.listen(1)

    def set_load_g(self, load_g: float) -> None:
        with self._lock:
            self.plant.set_load(load_g)

    def wait_connected(self, timeout_s: float) -> None:
        """Accept the harness; raise TimeoutError or ConnectionError naming the socket."""
        self._listener.settimeout(timeout_s)
        try:
            conn, _ = self._listener.accept()
        except socket.timeout:
            raise TimeoutError(f"the simavr harness did not connect to {self.path} within {timeout_s:g} s") from None
        conn.settimeout(timeout_s)
        hello = _recv_exactly(conn, len(HELLO))
        if hello != HELLO:
            conn.close()
            raise ConnectionError(f"{self.path}: expected the harness hello {HELLO!r}, got {hello!r}")
        conn.settimeout(None)
        self._conn = conn

    def start(self) -> None:
        """Release the AVR from reset and serve queries in a daemon thread."""
        if self._conn is None:
            raise RuntimeError("start() before wait_connected()")
        self._conn.sendall(b"G")
        self._thread = threading.Thread(target=self._serve, name="simavr-plant", daemon=True)
        self._thread.start()

    def close(self) -> None:
        for s in (self._conn, self._listener):
            if s is not None:
                try:
                    s.close()
                except OSError:
                    pass
        if self._thread is not None:
            self._thread.join(2.0)
        if os.path.exists(self.path):
            os.unlink(self.path)

    def answer(self, kind: int, moving: int, steps: int, t_s: float, duty: float) -> tuple[int, int]:
        """One query's ``(counts, flags)``; raises ValueError on a malformed request."""
        if kind not in (ord("L"), ord("R")) or not (0.0 <= duty <= 1.0) or not math.isfinite(t_s):
            raise ValueError(f"malformed plant request kind={kind} duty={duty} t={t_s}")
        with self._lock:
            reading = self.plant.sample(t_s, steps / self.steps_per_turn,
                                        self.heater_supply_V * math.sqrt(duty), bool(moving))
        self.queries += 1
        if kind == ord("L"):
            return self.sensors.position_raw(reading.length_mm), 0
        counts, flags = self.sensors.resistance_raw(reading.resistance_ohm)
        return counts, 1 if flags else 0

    def _serve(self) -> None:
        conn = self._conn
        assert conn is not None
        try:
            while True:
                data = _recv_exactly(conn, _REQUEST.size)
                if not data:
                    return
                counts, flags = self.answer(*_REQUEST.unpack(data))
                conn.sendall(_REPLY.pack(counts, flags))
        except (OSError, ValueError) as exc:
            self.error = f"plant server: {exc}"
            try:
                conn.close()
            except OSError:
                pass


def _recv_exactly(conn: socket.socket, n: int) -> bytes:
    """``n`` bytes, or b"" when the peer closed cleanly before sending any."""
    buf = bytearray()
    while len(buf) < n:
        chunk = conn.recv(n - len(buf))
        if not chunk:
            if buf:
                raise ConnectionError(f"plant socket closed mid-request ({len(buf)} of {n} bytes)")
            return b""
        buf += chunk
    return bytes(buf)
