"""``--zenoh-config FILE``: zenoh's own configuration under the command line's options, its errors
as one line before anything starts; and every node's log of losing and regaining its router."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time

import pytest

from helpers import wait_for
from hydromon.bus.session import free_tcp_endpoint, make_config, summarize_config
from hydromon.cli.main import main

pytestmark = pytest.mark.timeout(60)
NODE_COMMANDS = ["sim", "monitor", "record", "replay", "watch", "router", "demo"]


def _file(tmp_path, text: str, name: str = "z.json5"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _get(conf, key):
    return json.loads(conf.get_json(key))


# -- precedence ------------------------------------------------------------------------------------
def test_the_files_mode_and_endpoints_stay_unless_the_option_is_given(tmp_path):
    f = _file(tmp_path, '{ mode: "client", connect: { endpoints: ["tcp/10.0.0.1:7447"] },'
                        ' listen: { endpoints: ["tcp/127.0.0.1:7000"] }, queries_default_timeout: 1234 }')
    conf = make_config(None, (), (), False, f)
    assert _get(conf, "mode") == "client"
    assert _get(conf, "connect/endpoints") == ["tcp/10.0.0.1:7447"]
    assert _get(conf, "listen/endpoints") == ["tcp/127.0.0.1:7000"]
    assert _get(conf, "queries_default_timeout") == 1234  # what the options do not touch stays
    assert _get(conf, "scouting/multicast/enabled") is False  # not set in the file: off

    conf = make_config("peer", ["tcp/127.0.0.1:1"], ["tcp/127.0.0.1:2"], True, f)
    assert _get(conf, "mode") == "peer"
    assert _get(conf, "connect/endpoints") == ["tcp/127.0.0.1:1"]
    assert _get(conf, "listen/endpoints") == ["tcp/127.0.0.1:2"]
    assert _get(conf, "scouting/multicast/enabled") is True
    assert _get(conf, "queries_default_timeout") == 1234


def test_multicast_scouting_is_off_unless_the_option_or_the_file_turns_it_on(tmp_path):
    assert _get(make_config(), "scouting/multicast/enabled") is False
    assert _get(make_config(None, (), (), False, _file(tmp_path, "{}")), "scouting/multicast/enabled") is False
    on = _file(tmp_path, "{ scouting: { multicast: { enabled: true } } }", "on.json5")
    assert _get(make_config(None, (), (), False, on), "scouting/multicast/enabled") is True
    assert _get(make_config(None, (), (), False, None), "mode") == "peer"  # hydromon's default


def test_the_summary_reads_per_mode_endpoints_and_ignores_zenohs_default_listeners(tmp_path):
    f = _file(tmp_path, '{ mode: "client", connect: { endpoints: { client: ["tls/r:7447"], peer: [] } } }')
    s = summarize_config(make_config(None, (), (), False, f))
    assert (s.mode, s.connect, s.listen, s.multicast) == ("client", ["tls/r:7447"], [], False)


def test_the_router_listens_where_the_file_says_else_on_loopback(tmp_path):
    from hydromon.cli.commands.router import router_config

    assert router_config(None)[1] == ["tcp/127.0.0.1:7447"]
    f = _file(tmp_path, '{ mode: "client", listen: { endpoints: ["tls/0.0.0.0:7447"] } }')
    conf, listen = router_config(None, config_file=f)
    assert listen == ["tls/0.0.0.0:7447"] and _get(conf, "mode") == "router"  # a router, whatever the file says
    assert router_config(["tcp/127.0.0.1:9"], config_file=f)[1] == ["tcp/127.0.0.1:9"]


# -- errors: one line naming the file, exit 2, before anything starts -------------------------------
BAD_FILES = [
    ("{ mode: \"clint\" }", "unknown variant `clint`"),
    ("{ mode: \"client\", ", "(line 1, column"),
    ("{ modez: 1 }", "unknown field `modez`"),
    ("{ transport: { link: { tls: { root_ca_certificate: \"/nonexistent/ca.pem\" } } } }",
     "root_ca_certificate '/nonexistent/ca.pem': no such file"),
]


@pytest.mark.parametrize("command", NODE_COMMANDS)
@pytest.mark.parametrize("text, needle", BAD_FILES)
def test_a_bad_zenoh_config_is_one_error_line_naming_the_file(tmp_path, capsys, monkeypatch, command, text, needle):
    def refuse(*_a, **_k):
        raise AssertionError("the command ran with a bad --zenoh-config")

    monkeypatch.setattr("zenoh.open", refuse)
    f = _file(tmp_path, text)
    args = [command] + ([str(tmp_path / "r.mcap")] if command == "replay" else []) + ["--zenoh-config", str(f)]
    assert main(args) == 2
    cap = capsys.readouterr()
    err = cap.err.strip()
    assert "\n" not in err and err.startswith(f"hydromon {command}: error: --zenoh-config {f}"), err
    assert needle in err, err


def test_a_missing_zenoh_config_file_is_named(tmp_path, capsys):
    assert main(["watch", "--once", "--zenoh-config", str(tmp_path / "nope.json5")]) == 2
    assert capsys.readouterr().err.strip() == f"hydromon watch: error: --zenoh-config {tmp_path / 'nope.json5'}: no such file"


# -- losing and regaining the router ----------------------------------------------------------------
ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}
_CUT = re.compile(r"hydromon record: cut off: lost zenoh router (\w+) at ")
_BACK = re.compile(r"hydromon record: reconnected to zenoh router (\w+) at \S+, after ([\d.]+) s cut off")


def _router(ep, log):
    return subprocess.Popen([sys.executable, "-m", "hydromon.cli", "router", "--listen", ep],
                            stdout=log, stderr=log, stdin=subprocess.DEVNULL, env=ENV)


def _wait_line(path, pattern, timeout_s, what, proc):
    def alive():
        if proc.poll() is not None:
            raise AssertionError(f"the node exited ({proc.returncode}): {path.read_text()[-2000:]}")

    found = []
    wait_for(lambda: found.extend(pattern.findall(path.read_text())) or found, timeout_s, what, alive=alive, poll_s=0.05)
    return found[0]


@pytest.mark.network
def test_a_node_logs_losing_its_router_and_reconnecting_with_how_long_it_was_cut_off(tmp_path):
    # the client's retry period comes from a zenoh file; mode and endpoint from the options on top
    retry = _file(tmp_path, "{ connect: { retry: { period_init_ms: 250, period_max_ms: 1000 } } }")
    ep = free_tcp_endpoint()
    node_log, router_log = tmp_path / "record.log", tmp_path / "router.log"
    with open(router_log, "ab") as rlog, open(node_log, "wb") as nlog:
        router = _router(ep, rlog)
        node = None
        try:
            wait_for(lambda: "listening on" in router_log.read_text(), 30, "the router")
            node = subprocess.Popen([sys.executable, "-m", "hydromon.cli", "record", "--out", str(tmp_path / "r.mcap"),
                                     "--mode", "client", "--connect", ep, "--zenoh-config", str(retry)],
                                    stdout=nlog, stderr=nlog, stdin=subprocess.DEVNULL, env=ENV)
            wait_for(lambda: "writing" in node_log.read_text(), 30, "the recorder")
            time.sleep(0.5)
            router.kill()
            router.wait(10)
            first = _wait_line(node_log, _CUT, 10, "the line saying the router was lost", node)
            down_s = 2.0
            time.sleep(down_s)
            router = _router(ep, rlog)
            wait_for(lambda: router_log.read_text().count("listening on") == 2, 30, "the router again", poll_s=0.01)
            up = time.monotonic()
            back = _wait_line(node_log, _BACK, 20, "the line saying it reconnected", node)
            print(f"router down {down_s:g} s (plus its start): the node logged 'reconnected' "
                  f"{time.monotonic() - up:.2f} s after the router listened again, cut off {back[1]} s")
            assert back[0] != first  # a restarted router is another zenoh node
            assert down_s <= float(back[1]) < down_s + 10
            text = node_log.read_text()
            assert text.count("cut off: lost") == 1 and text.count("reconnected to") == 1
            assert "no zenoh node reached" not in text  # it had reached one: the cut says so itself
            node.send_signal(signal.SIGINT)
            assert node.wait(20) == 0, node_log.read_text()
            assert node_log.read_text().count("cut off: lost") == 1  # its own stop is not a loss
        finally:
            for p in (node, router):
                if p is not None and p.poll() is None:
                    p.kill()
                    p.wait(10)


@pytest.mark.network
def test_the_demos_session_takes_the_file_and_listens_where_it_says_else_on_a_free_loopback_port(tmp_path):
    from hydromon.bus.demo import _demo_session

    plain = _file(tmp_path, "{ queries_default_timeout: 1234 }")
    with _demo_session(plain) as (session, endpoint):
        assert endpoint.startswith("tcp/127.0.0.1:") and not session.is_closed()
        with open_session_to(endpoint) as other:
            wait_for(lambda: list(other.info.peers_zid()), 10, "the demo's session")
    ep = free_tcp_endpoint()
    listening = _file(tmp_path, f'{{ listen: {{ endpoints: ["{ep}"] }} }}', "listen.json5")
    with _demo_session(listening) as (session, endpoint):
        assert endpoint == ep


def open_session_to(endpoint):
    from hydromon.bus.session import open_session

    return open_session("peer", connect=[endpoint])
