"""Transports to the bench device: the ``sim://`` pyserial URL handler and a pty server.

Importing this package registers ``sim://`` with pyserial: it appends
``tsa_bench.transport`` to ``serial.protocol_handler_packages`` (once), so
``serial.serial_for_url("sim://...")`` finds :mod:`tsa_bench.transport.protocol_sim`.
"""

import serial

if "tsa_bench.transport" not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append("tsa_bench.transport")

from tsa_bench.transport.protocol_sim import Pacer, SimUrl, parse_sim_url  # noqa: E402

__all__ = ["Pacer", "SimUrl", "parse_sim_url", "serve_pty"]


def __getattr__(name: str):
    """``serve_pty`` on first use: a ``sim://`` run does not need the pty server."""
    if name == "serve_pty":
        from tsa_bench.transport.pty_server import serve_pty

        return serve_pty
    raise AttributeError(f"module 'tsa_bench.transport' has no attribute {name!r}")
