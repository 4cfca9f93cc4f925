"""Listening on loopback without losing the race for the port.

``free_tcp_endpoint`` frees the port it found before the listener binds it: another process
(a parallel test, an outgoing connection given it as its local port) can take it in between,
and the listener fails with "Address already in use". ``on_a_free_port`` then starts the
listener again on another port: ``listening_session`` for a session of this process, and the
tests' helpers for a node process started with ``--listen``.
"""

from __future__ import annotations

import socket

import pytest

from helpers import held_port, taken_first, wait_for
from hydromon.bus import session as bus
from hydromon.bus.session import ADDRESS_IN_USE, listening_session, on_a_free_port, open_session

pytestmark = pytest.mark.network


def _port_is_bound(ep: str) -> bool:
    """Whether something listens on (or is bound to) the port: a TIME_WAIT left by a closed
    connection does not count (SO_REUSEADDR)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("127.0.0.1", int(ep.rsplit(":", 1)[1])))
        except OSError:
            return True
    return False


@pytest.mark.timeout(60)
@pytest.mark.parametrize("mode", ["peer", "router"])
def test_a_listening_session_comes_up_on_another_port_when_its_port_was_taken(monkeypatch, mode):
    held, taken = held_port()
    taken_first(monkeypatch, taken)
    with held, listening_session(mode) as (s, ep), listening_session(mode) as (_, other):
        host, port = ep.removeprefix("tcp/").rsplit(":", 1)
        assert host == "127.0.0.1" and int(port) > 0 and ep != taken and other not in (ep, taken)
        assert _port_is_bound(ep)
        with open_session("client" if mode == "router" else "peer", connect=[ep]) as c:
            sub = s.declare_subscriber("hydro/port-test")
            pub = c.declare_publisher("hydro/port-test")
            wait_for(lambda: pub.matching_status.matching, 20, "the subscription across the link")
            pub.put(b"x")
            assert sub.recv().payload.to_bytes() == b"x"
    assert not _port_is_bound(ep)  # closed with the session
    with pytest.raises(ValueError, match="peer or a router"), listening_session("client"):
        pass


@pytest.mark.timeout(60)
def test_a_taken_listen_port_is_a_connection_error_saying_so():
    held, ep = held_port()
    with held, pytest.raises(ConnectionError) as err:
        open_session("peer", listen=[ep])
    assert ep in str(err.value) and ADDRESS_IN_USE in str(err.value)


@pytest.mark.timeout(60)
def test_on_a_free_port_starts_again_on_another_port_when_its_port_was_taken(monkeypatch):
    held, taken = held_port()
    taken_first(monkeypatch, taken)
    calls = []

    def start(ep):
        calls.append(ep)
        return open_session("peer", listen=[ep])

    with held:
        session, ep = on_a_free_port(start)
        with session:
            assert calls == [taken, ep] and ep != taken and _port_is_bound(ep)

        # any other error is not retried; a port taken every time fails after `attempts`
        def refused(ep):
            calls.append(ep)
            raise ValueError("no")

        calls.clear()
        with pytest.raises(ValueError, match="no"):
            on_a_free_port(refused)
        assert len(calls) == 1
        monkeypatch.setattr(bus, "free_tcp_endpoint", lambda host="127.0.0.1": taken)
        calls.clear()
        with pytest.raises(ConnectionError, match=ADDRESS_IN_USE):
            on_a_free_port(start, attempts=3)
        assert calls == [taken] * 3


def test_zenoh_errors_lose_their_rust_source_paths():
    from hydromon.bus.session import _without_source_paths

    raw = ("Can not create a new TCP listener bound to tcp/127.0.0.1:44437: [127.0.0.1:44437: Address already in "
           "use (os error 98) at /root/.cargo/git/checkouts/zenoh-9c599d5ef3e0480e/cc83980/io/zenoh-link-commons/"
           "src/tcp.rs:61.] at /root/.cargo/git/checkouts/zenoh-9c599d5ef3e0480e/cc83980/io/zenoh-links/"
           "zenoh-link-tcp/src/unicast.rs:338.")
    assert _without_source_paths(raw) == ("Can not create a new TCP listener bound to tcp/127.0.0.1:44437: "
                                          "[127.0.0.1:44437: Address already in use (os error 98)]")
    assert _without_source_paths("Unable to connect to any of [Single(tcp/127.0.0.1:1)]!") == \
        "Unable to connect to any of [Single(tcp/127.0.0.1:1)]!"


@pytest.mark.network
@pytest.mark.timeout(60)
def test_a_node_whose_connect_reaches_nobody_says_so(capsys):
    # `hydromon record --connect tcp/127.0.0.1:1 --duration 1` (a peer: zenoh opens and keeps
    # retrying) must say that its endpoint reached nobody, not write an empty recording in silence
    from hydromon.bus.session import warn_if_not_connected

    with socket.socket() as held:  # bound, not listening: a connect is refused
        held.bind(("127.0.0.1", 0))
        dead = f"tcp/127.0.0.1:{held.getsockname()[1]}"
        with open_session("peer", connect=[dead]) as alone:
            warn_if_not_connected(alone, "record", [dead], after_s=0.3).join(10)
        err = capsys.readouterr().err
        assert "hydromon record: warning: no zenoh node reached after 0.3 s through --connect " + dead in err
        with listening_session() as (_, ep), open_session("peer", connect=[ep]) as linked:
            timer = warn_if_not_connected(linked, "record", [ep], after_s=1.0)
            timer.join(10)
        assert capsys.readouterr().err == ""
        assert warn_if_not_connected(linked, "record", []) is None  # nothing to reach: no check
