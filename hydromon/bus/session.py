"""Zenoh plumbing shared by every node: sessions, JSON payloads, loopback endpoints.

Nodes take an open ``zenoh.Session``; this module is how one is made (the command line's
options for it are ``hydromon.cli.busopts``).
Multicast scouting is off unless asked for, so a node only talks to the endpoints it is
given (``--connect``/``--listen``) and tests on loopback never meet strangers.

A node's zenoh configuration may start from a zenoh configuration file (JSON5, zenoh's own
format: TLS, access control, timeouts...; :func:`load_config_file`); the mode, endpoints and
multicast scouting given as arguments are set on top of it, and only those given
(:func:`make_config` says which wins where).
"""

from __future__ import annotations

import json
import os
import re
import sys
import threading
import socket
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import TypeVar

import orjson
import zenoh


__all__ = [
    "MODES", "JSON", "open_session", "make_config", "free_tcp_endpoint", "listening_session",
    "on_a_free_port", "ADDRESS_IN_USE", "endpoints", "warn_if_not_connected", "dumps", "loads",
    "DEFAULT_ROUTER_ENDPOINT", "load_config_file", "config_endpoints", "ConfigSummary", "summarize_config",
]

MODES = ("peer", "client", "router")
DEFAULT_ROUTER_ENDPOINT = "tcp/127.0.0.1:7447"
JSON = zenoh.Encoding.APPLICATION_JSON
"""Encoding of every contract payload."""
ADDRESS_IN_USE = "Address already in use"
"""In the error of a listener whose port is taken (the OS's text for EADDRINUSE, in zenoh's error)."""
_T = TypeVar("_T")


def endpoints(name: str, values: Iterable[str] | str | None) -> list[str]:
    """``values`` as a list of zenoh endpoints ``PROTO/ADDRESS``; ValueError naming ``name`` if one is not."""
    if values is None:
        return []
    if isinstance(values, str):
        values = [values]
    out = []
    for v in values:
        if not isinstance(v, str) or "/" not in v or not v.split("/", 1)[1]:
            raise ValueError(f"{name} endpoint {v!r}: expected PROTO/ADDRESS, e.g. tcp/127.0.0.1:7447")
        out.append(v)
    return out


_TLS_FILES = ("root_ca_certificate", "listen_private_key", "listen_certificate", "connect_private_key",
              "connect_certificate")
_ZENOH_MESSAGE = re.compile(r'Message \{ msg: "(?P<msg>.*?)", location: Some\(Location \{ line: (?P<line>\d+), '
                            r'column: (?P<col>\d+) \}\) \}', re.S)
_PEST_ERROR = re.compile(r"-->\s*(?P<line>\d+):(?P<col>\d+).*?=\s*(?P<msg>.*)$", re.S)


def _config_reason(text: str) -> str:
    """zenoh's reason for refusing a configuration, on one line (what, and the line and column
    in the file when zenoh gives them)."""
    text = _without_source_paths(text)
    m = _ZENOH_MESSAGE.search(text) or _PEST_ERROR.search(text)
    if m:
        return f"{' '.join(m.group('msg').split())} (line {m.group('line')}, column {m.group('col')})"
    return " ".join(text.split())


def load_config_file(path) -> zenoh.Config:
    """``zenoh.Config.from_file(path)``: zenoh's JSON5 configuration file, checked.

    ValueError on one line, naming the file and zenoh's reason, when the file is missing,
    unreadable or not a zenoh configuration (a syntax error, an unknown field, a bad value);
    also when a TLS file it names (``transport/link/tls``: the CA, keys and certificates) cannot
    be read, which zenoh would say only when the session opens.
    """
    name = os.fspath(path)
    if not os.path.isfile(name):
        raise ValueError(f"--zenoh-config {name}: no such file")
    try:
        conf = zenoh.Config.from_file(name)
    except zenoh.ZError as exc:
        raise ValueError(f"--zenoh-config {name}: not a zenoh configuration: {_config_reason(str(exc))}") from None
    tls = json.loads(conf.get_json("transport/link/tls"))
    for field in _TLS_FILES:
        value = tls.get(field)
        if isinstance(value, str) and not os.access(value, os.R_OK):
            why = "no such file" if not os.path.exists(value) else "not readable"
            raise ValueError(f"--zenoh-config {name}: transport/link/tls/{field} {value!r}: {why}")
    return conf


_DEFAULT_LISTEN = None


def _default_listen() -> str:
    global _DEFAULT_LISTEN
    if _DEFAULT_LISTEN is None:
        _DEFAULT_LISTEN = zenoh.Config().get_json("listen/endpoints")
    return _DEFAULT_LISTEN


def config_endpoints(conf: zenoh.Config, which: str, mode: str) -> list[str]:
    """The ``connect`` or ``listen`` endpoints ``conf`` sets for a node in ``mode`` (zenoh
    accepts a list, or one list per mode); [] where it sets none (zenoh's own default
    listeners are not counted)."""
    raw = conf.get_json(f"{which}/endpoints")
    if which == "listen" and raw == _default_listen():
        return []
    value = json.loads(raw)
    if isinstance(value, dict):
        value = value.get(mode) or []
    return [v for v in value if isinstance(v, str)] if isinstance(value, list) else []


def make_config(mode: str | None = None, connect: Iterable[str] = (), listen: Iterable[str] = (),
                multicast: bool = False, config_file=None) -> zenoh.Config:
    """A ``zenoh.Config`` for ``mode`` (peer|client|router) with the given endpoints.

    Parameters
    ----------
    mode : str or None
        The zenoh mode; None: the file's, else ``peer``.
    connect, listen : iterable of str
        Zenoh endpoints such as ``tcp/127.0.0.1:7447``; given ones replace the file's, none
        keep the file's.
    multicast : bool
        Enable multicast scouting. False leaves it as the file sets it, and off when the file
        does not set it (zenoh's own default is on): nodes meet only through the explicit
        endpoints (a peer given no ``listen`` still listens on a random port of every
        interface, zenoh's default, which no other node can know).
    config_file : path or None
        A zenoh configuration file (:func:`load_config_file`) to start from.
    """
    if mode is not None and mode not in MODES:
        raise ValueError(f"zenoh mode {mode!r}: choose one of {', '.join(MODES)}")
    connect, listen = endpoints("connect", connect), endpoints("listen", listen)
    conf = zenoh.Config() if config_file is None else load_config_file(config_file)
    if mode is not None or conf.get_json("mode") == "null":
        conf.insert_json5("mode", json.dumps(mode or "peer"))
    if connect:
        conf.insert_json5("connect/endpoints", json.dumps(connect))
    if listen:
        conf.insert_json5("listen/endpoints", json.dumps(listen))
    if multicast or conf.get_json("scouting/multicast/enabled") == "null":
        conf.insert_json5("scouting/multicast/enabled", json.dumps(bool(multicast)))
    return conf


class ConfigSummary:
    """What a node's configuration says about whom it can meet: its mode, the endpoints it
    connects to and listens on (from the arguments or the file), multicast scouting."""

    def __init__(self, mode: str, connect: list[str], listen: list[str], multicast: bool):
        self.mode, self.connect, self.listen, self.multicast = mode, connect, listen, multicast


def summarize_config(conf: zenoh.Config) -> ConfigSummary:
    mode = json.loads(conf.get_json("mode")) or "peer"
    return ConfigSummary(mode, config_endpoints(conf, "connect", mode), config_endpoints(conf, "listen", mode),
                         json.loads(conf.get_json("scouting/multicast/enabled")) is True)


_SOURCE_PATH = re.compile(r"\s+at (?:/|[A-Za-z]:\\)\S*?\.rs:\d+(?::\d+)?\.?")


def _without_source_paths(reason: str) -> str:
    """zenoh's error text without the Rust source locations it appends (`` at /root/.cargo/...
    /tcp.rs:61``, one per nested error): a user reads what failed, not where in zenoh."""
    return _SOURCE_PATH.sub("", reason).strip()


def open_session(mode: str | None = None, connect: Iterable[str] = (), listen: Iterable[str] = (),
                 multicast: bool = False, config_file=None, config: zenoh.Config | None = None) -> zenoh.Session:
    """Open a zenoh session (see :func:`make_config`, or ``config`` made by it); close it with
    ``with`` or ``.close()``.

    ConnectionError (one line: the mode, the endpoints, the configuration file and zenoh's
    reason) if zenoh cannot open it: a client whose router is not up or refuses its TLS
    handshake (zenoh does not wait for it), a port already in use.
    """
    connect, listen = endpoints("connect", connect), endpoints("listen", listen)
    conf = config if config is not None else make_config(mode, connect, listen, multicast, config_file)
    try:
        return zenoh.open(conf)
    except zenoh.ZError as exc:
        summary = summarize_config(conf)
        where = "".join(f", {name} {', '.join(eps)}" for name, eps in
                        (("connect", summary.connect), ("listen", summary.listen)) if eps)
        if config_file is not None:
            where += f", --zenoh-config {os.fspath(config_file)}"
        reason = " ".join(_without_source_paths(str(exc)).split())
        raise ConnectionError(f"cannot open the zenoh session ({summary.mode}{where}): {reason}") from None


def free_tcp_endpoint(host: str = "127.0.0.1") -> str:
    """``tcp/HOST:PORT`` for a port that was free a moment ago.

    Racy: the port is free only until someone binds it, and between this call and the listener's
    bind another process may (a parallel test, or the OS picking it as the local port of an
    outgoing connection: it is in the ephemeral range). Listeners should use
    :func:`listening_session` (a session of this process) or :func:`on_a_free_port`.
    """
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        port = s.getsockname()[1]
    return f"tcp/{host}:{port}"


@contextmanager
def listening_session(mode: str = "peer", host: str = "127.0.0.1",
                      attempts: int = 5, config_file=None) -> Iterator[tuple[zenoh.Session, str]]:
    """``(session, endpoint)``: a session (``peer`` or ``router``) listening on ``endpoint``, a
    ``tcp/HOST:PORT`` for other sessions to ``connect`` to; closed on leaving the ``with``.

    The port was found free (:func:`free_tcp_endpoint`); if another process took it before the
    session bound it, the session is opened on another (:func:`on_a_free_port`). The session's
    config is a node's (:func:`open_session`). (zenoh-python 1.10 can listen on port 0, but tells
    the port it bound only in the session's admin space, ``@/<zid>/<mode>``, which is off unless
    ``adminspace/enabled`` is set.)
    """
    if mode not in ("peer", "router"):
        raise ValueError(f"zenoh mode {mode!r}: a listening session is a peer or a router")
    session, endpoint = on_a_free_port(lambda ep: open_session(mode, listen=[ep], config_file=config_file),
                                       host, attempts)
    with session:
        yield session, endpoint


def on_a_free_port(start: Callable[[str], _T], host: str = "127.0.0.1", attempts: int = 5) -> tuple[_T, str]:
    """``(start(endpoint), endpoint)`` for a listener on a port found free: ``start`` is called
    with :func:`free_tcp_endpoint` and, while it raises an error whose text says
    :data:`ADDRESS_IN_USE` (the port was taken between the pick and the bind), with a new port,
    ``attempts`` times in all; any other error is raised at once. For a node in another process
    (``--listen endpoint``), ``start`` waits until the node is up or has exited, and raises with
    the node's output."""
    for attempt in range(1, attempts + 1):
        endpoint = free_tcp_endpoint(host)
        try:
            return start(endpoint), endpoint
        except Exception as exc:
            if ADDRESS_IN_USE not in str(exc) or attempt == attempts:
                raise
    raise ValueError(f"attempts {attempts!r} must be >= 1")


NOT_CONNECTED_AFTER_S = 5.0
"""A node given --connect endpoints that has reached no other node after this long says so."""


def warn_if_not_connected(session: zenoh.Session, name: str, connect: list[str],
                          after_s: float = NOT_CONNECTED_AFTER_S,
                          reached: Callable[[], bool] | None = None) -> threading.Timer | None:
    """Once, ``after_s`` [s] from now: if the session has no router and no peer, say on stderr
    that ``--connect`` reached nobody. A peer whose endpoint is down (a typo, the other node not
    started) opens anyway and zenoh keeps retrying in silence: a recorder ran its whole
    ``--duration`` and wrote an empty file with exit status 0, saying nothing. ``reached()``,
    if given, tells whether the node has reached one at any time since it started (one cut off
    since says so itself: :mod:`hydromon.bus.connectivity`)."""
    if not connect:
        return None

    def check() -> None:
        try:
            if session.is_closed() or list(session.info.routers_zid()) or list(session.info.peers_zid()):
                return
            if reached is not None and reached():
                return
        except zenoh.ZError:  # closed meanwhile
            return
        print(f"hydromon {name}: warning: no zenoh node reached after {after_s:g} s through --connect "
              f"{', '.join(connect)} (is it running, and is that its --listen endpoint? zenoh keeps trying)",
              file=sys.stderr, flush=True)

    timer = threading.Timer(after_s, check)
    timer.daemon = True
    timer.start()
    return timer


def dumps(obj) -> bytes:
    """JSON bytes of a payload (a dict of plain numbers/strings, or a pydantic model)."""
    if hasattr(obj, "model_dump"):
        obj = obj.model_dump(mode="json")
    return orjson.dumps(obj)


def loads(data) -> object:
    """Parse JSON from bytes, str or a ``zenoh.ZBytes``; raise ValueError on bad JSON."""
    if isinstance(data, zenoh.ZBytes):
        data = data.to_bytes()
    try:
        return orjson.loads(data)
    except orjson.JSONDecodeError as exc:
        raise ValueError(f"payload is not JSON: {exc}") from None
