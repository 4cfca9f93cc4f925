"""The dashboard's web server: uvicorn serving :func:`hydromon.dashboard.app.build_app` in a
thread, on a socket bound before it starts (so the URL is known, and a port taken is an error
at once).
"""

from __future__ import annotations

import ipaddress
import socket
import threading

import uvicorn

from hydromon.dashboard.app import build_app
from hydromon.dashboard.fleet import Fleet

__all__ = ["WebServer", "bind", "is_loopback"]


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (port 0: a free one); OSError naming the address."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host.strip("[]"), port))
        sock.listen(128)
    except OSError as exc:
        sock.close()
        raise OSError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    sock.set_inheritable(True)
    return sock


class WebServer:
    """uvicorn in a daemon thread serving ``fleet``; :attr:`url`; :meth:`close` stops it."""

    def __init__(self, fleet: Fleet, host: str = "127.0.0.1", port: int = 8050, on_tick=None,
                 info: dict | None = None, clock=None):
        self.info = dict(info or {})  # what the pages are told of the source (``/api/info``)
        self.sock = bind(host, port)
        self.port = self.sock.getsockname()[1]
        shown = f"[{host.strip('[]')}]" if ":" in host else host
        self.url = f"http://{shown}:{self.port}/"
        kw = {} if clock is None else {"clock": clock}
        app = build_app(fleet, loopback_only=is_loopback(host), on_tick=on_tick, info=info, **kw)
        config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="on", ws="websockets-sansio",
                                ws_ping_interval=20, ws_ping_timeout=20)
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.server.run, kwargs={"sockets": [self.sock]},
                                       name="dashboard-http", daemon=True)

    def start(self, timeout_s: float = 10.0) -> WebServer:
        self.thread.start()
        self.thread.join(0)
        for _ in range(int(timeout_s / 0.02)):
            if self.server.started or not self.thread.is_alive():
                break
            threading.Event().wait(0.02)
        if not self.server.started:
            raise RuntimeError("the dashboard's web server did not start")
        return self

    def close(self, timeout_s: float = 10.0) -> None:
        self.server.should_exit = True
        if self.thread.is_alive():
            self.thread.join(timeout_s)
        self.sock.close()
