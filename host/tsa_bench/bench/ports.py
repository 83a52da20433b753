"""Which serial ports a bench file or ``--port`` may name.

Policy: a serial device path (``/dev/ttyACM0``, ``/dev/pts/7``, ``COM3``: anything
without ``://``) or the simulated bench ``sim://...``. Every other pyserial URL is
refused unless the user passes ``--allow-url``, because pyserial's URL handlers do
more than open a port: ``spy://...?file=PATH`` writes a traffic dump to any path,
``socket://`` and ``rfc2217://`` open network connections, ``hwgrep://`` opens
whatever device matches a pattern.
"""

from __future__ import annotations

SIM_SCHEME = "sim://"


class PortPolicyError(ValueError):
    """A port the policy refuses; the message says why and how to allow it."""


def check_port(port: object, *, allow_url: bool = False) -> str:
    """Return ``port`` when the policy allows it; raise PortPolicyError otherwise."""
    if not isinstance(port, str) or not port.strip():
        raise PortPolicyError(f"port must be a serial device path or sim://, got {port!r}")
    if any(ch in port for ch in "\x00\n\r"):
        raise PortPolicyError(f"port {port!r} holds a control character")
    if "://" not in port or port.lower().startswith(SIM_SCHEME):
        return port
    scheme = port.split("://", 1)[0]
    if allow_url:
        return port
    raise PortPolicyError(
        f"port {port!r} is a pyserial {scheme}:// URL; only serial device paths (e.g. /dev/ttyACM0, COM3) "
        f"and sim:// are allowed, because other URLs can write files or open network connections; "
        f"pass --allow-url to use it anyway")
