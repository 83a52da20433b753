"""`tsa-bench serve`: the page on uvicorn, bound to this machine only unless asked.

Contract: :func:`check_address` refuses an address that is not loopback (127.0.0.0/8,
::1, ``localhost``) unless ``allow_remote``: the page has no login, and anyone who can
reach the address would see every rig and run. :func:`serve` binds the socket itself (so
``port`` 0 takes a free port and the URL printed is the one that answers), says the URL
on ``say`` once the socket listens, and runs until Ctrl-C or SIGTERM. Figures go to
``cache_dir``, or to a temporary folder removed at the end; nothing else is written.
"""

from __future__ import annotations

import ipaddress
import shutil
import socket
import tempfile
from collections.abc import Callable
from pathlib import Path

LOOPBACK_NAMES = {"localhost", "localhost.localdomain", "ip6-localhost"}


class ServeError(RuntimeError):
    """The page cannot be served; the message says why and what to do."""


def is_loopback(host: str) -> bool:
    """127.0.0.0/8, ::1 or a loopback name."""
    if host.lower() in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def check_address(host: str, allow_remote: bool) -> None:
    """ServeError for an address other machines can reach, unless ``allow_remote``."""
    if not is_loopback(host) and not allow_remote:
        raise ServeError(
            f"refusing to listen on {host}: the page has no login, so anyone who can reach {host} would see every "
            "rig and run of this lab. Listen on 127.0.0.1 (the default) and reach it through `ssh -L`, or give "
            "--allow-remote to serve it on a network you trust.")


def bind(host: str, port: int) -> socket.socket:
    """A listening socket on (host, port); ServeError naming the address when it cannot be had."""
    try:
        infos = socket.getaddrinfo(host.strip("[]"), port, type=socket.SOCK_STREAM)
    except socket.gaierror as exc:
        raise ServeError(f"cannot listen on {host}: {exc.strerror or exc}") from None
    family, _, _, _, address = infos[0]
    sock = socket.socket(family, socket.SOCK_STREAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(address)
        sock.listen(128)
    except OSError as exc:
        sock.close()
        why = "the port is in use (another tsa-bench serve?); give --port" if exc.errno == 98 else exc.strerror or exc
        raise ServeError(f"cannot listen on {host}:{port}: {why}") from None
    return sock


def url_of(sock: socket.socket) -> str:
    host, port = sock.getsockname()[:2]
    return f"http://[{host}]:{port}/" if ":" in host else f"http://{host}:{port}/"


def serve(runs_dir: str | Path | None, catalogue: str | None, *, host: str = "127.0.0.1", port: int = 8765,
          allow_remote: bool = False, cache_dir: str | Path | None = None, poll_s: float = 0.25,
          say: Callable[[str], None] = print) -> None:
    """Serve the page until interrupted (module contract); ServeError when it cannot start."""
    check_address(host, allow_remote)
    try:
        import uvicorn

        from tsa_bench.web.app import create_app
    except ImportError as exc:
        raise ServeError(f"the web page needs the [web] extra ({exc.name} is not installed): "
                         "pip install 'tsa-bench[web]'") from None
    temp = None
    if cache_dir is None:
        temp = cache_dir = tempfile.mkdtemp(prefix="tsa-bench-serve-")
    sock = bind(host, port)
    try:
        hosts = ["*"] if allow_remote else None
        app = create_app(runs_dir, catalogue, cache_dir, poll_s=poll_s, allowed_hosts=hosts)
        config = uvicorn.Config(app, log_level="warning", timeout_graceful_shutdown=2, access_log=False,
                                lifespan="on")
        view = app.state.server.view
        say(f"serving the lab page on {url_of(sock)}  (runs: {runs_dir}; catalogue: "
            f"{view.shown if view else 'none'}; Ctrl-C stops)")
        uvicorn.Server(config).run(sockets=[sock])
    finally:
        sock.close()
        if temp is not None:
            shutil.rmtree(temp, ignore_errors=True)
