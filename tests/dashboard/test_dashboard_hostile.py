"""Text from the bus never becomes markup or script on the dashboard's pages.

A rig id and a monitor's node name are ``[A-Za-z0-9_-]`` by the contract, but a health payload's
parameter names (``params``, ``param_grades`` keys) and its ``ranges``, and an event's ``from``,
``to`` and ``reason``, are free text; so is an acknowledgement's comment. A peer publishes such
payloads full of markup; a dashboard (in this process, on loopback) serves them to headless
Chromium, which must show them as text: no element made from them, no dialog opened, no error.
The server's own guards are checked too: the Content-Security-Policy on every response, a
``Host`` that is not loopback refused, an acknowledgement from another origin refused.
"""

from __future__ import annotations

import http.client
import time

import orjson
import pytest

from helpers import wait_for
from hydromon.bus.session import listening_session, open_session
from hydromon.contract import Event, Health
from hydromon.dashboard.app import CSP
from hydromon.dashboard.service import open_live
from webhelpers import Watched, chromium

XSS = ['<img src=x onerror="alert(1)">', "</td><script>alert(2)</script>", "<svg onload=alert(3)>",
       "\"'><b>bold</b>&amp;"]


def _health(seq: int) -> bytes:
    params = {"K_sv": 1e-4, XSS[0]: 1.0, XSS[1]: 2.0}
    h = Health(seq=seq, t=seq * 0.1, grade="fault", level=4, confidence=0.5, params=params,
               param_grades={"K_sv": "fault", XSS[0]: "fault", XSS[1]: "fault"}, status="ok",
               std_errors={"K_sv": 1e-6}, ranges=XSS[2], node="evil-node", epoch=1)
    return h.model_dump_json().encode()


def _event() -> bytes:
    ev = Event.model_validate({"seq": 1, "t": 0.1, "kind": "grade", "from": "<i>x</i>", "to": "<b>fault</b>",
                               "reason": XSS[0] + XSS[1] + XSS[3], "node": "evil-node"})
    return orjson.dumps(ev.model_dump(by_alias=True))


def _request(port: int, method: str, path: str, headers=None, body: bytes | None = None):
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    try:
        c.request(method, path, body=body, headers=headers or {})
        r = c.getresponse()
        return r.status, dict(r.getheaders()), r.read()
    finally:
        c.close()


INJECTED = "() => document.querySelectorAll('main img, main script, main svg, main b, td i, main iframe').length"


@pytest.mark.network
@pytest.mark.timeout(120)
def test_hostile_payload_text_is_shown_as_text(tmp_path):
    with listening_session("peer") as (pub, ep), open_session("peer", connect=[ep]) as sub_session:
        token = pub.liveliness().declare_token("hydro/monitor/evil-node")
        dash = open_live(sub_session, port=0, events_path=tmp_path / "events.jsonl", wait_s=0.5)
        try:
            port = dash.web.port
            wait_for(lambda: dash.fleet.monitors.get("evil-node"), 10, "the token seen")
            for seq in range(5):
                pub.put("hydro/rig/rig-x/health", _health(seq))
                time.sleep(0.05)
            pub.put("hydro/rig/rig-x/event", _event())
            wait_for(lambda: dash.fleet.events.recent(), 10, "the event taken")
            ev_id = dash.fleet.events.recent()[0]["id"]

            # the server's guards
            for path in ("/", "/rig/rig-x", "/events", "/static/fleet.js", "/api/fleet"):
                status, headers, _ = _request(port, "GET", path)
                assert status == 200 and headers.get("content-security-policy") == CSP, (path, status, headers)
                assert headers.get("x-content-type-options") == "nosniff"
            assert _request(port, "GET", "/rig/%3Cscript%3E")[0] == 404
            assert _request(port, "GET", "/", {"Host": "attacker.example"})[0] == 421
            ack = orjson.dumps({"comment": XSS[0], "by": XSS[2]})
            status, _, _ = _request(port, "POST", f"/api/events/{ev_id}/ack",
                                    {"Origin": "http://attacker.example", "Content-Type": "application/json"}, ack)
            assert status == 403
            status, _, body = _request(port, "POST", f"/api/events/{ev_id}/ack",
                                       {"Origin": f"http://127.0.0.1:{port}", "Content-Type": "application/json"}, ack)
            assert status == 200, body
            again = orjson.dumps({"comment": "mine now", "by": "bob"})  # a second one never replaces the first
            same = {"Origin": f"http://127.0.0.1:{port}", "Content-Type": "application/json"}
            status, _, body = _request(port, "POST", f"/api/events/{ev_id}/ack", same, again)
            assert status == 409 and body.startswith(b"already acknowledged by "), (status, body)
            status, _, _ = _request(port, "POST", f"/api/events/{ev_id}/ack",
                                    {"Origin": f"http://127.0.0.1:{port}", "Content-Type": "application/json"},
                                    orjson.dumps({"comment": None, "by": ["x"]}))
            assert status == 400

            with chromium() as ctx:
                pages = {}
                for name, path in (("fleet", ""), ("rig", "rig/rig-x"), ("events", "events")):
                    w = pages[name] = Watched(ctx)
                    w.page.goto(dash.url + path)
                fleet, rig, events = pages["fleet"].page, pages["rig"].page, pages["events"].page
                wait_for(lambda: XSS[0] in fleet.evaluate("() => document.querySelector('#fleet tbody').textContent"),
                         10, "the hostile parameter name in the why column, as text")
                wait_for(lambda: XSS[1] in (rig.evaluate("() => document.querySelector('#why').textContent") or ""),
                         10, "the hostile words on the rig page, as text")
                wait_for(lambda: XSS[3] in events.evaluate("() => document.querySelector('#events tbody').textContent"),
                         10, "the hostile reason on the events page, as text")
                text = events.evaluate("() => document.querySelector('#events tbody').textContent")
                assert "<b>fault</b>" in text and "<i>x</i>" in text and XSS[2] in text  # the ack's name
                time.sleep(1.0)  # pushes after the snapshot
                for name, w in pages.items():
                    assert w.page.evaluate(INJECTED) == 0, name
                    assert w.dialogs == [], (name, w.dialogs)
                    assert w.errors == [], (name, w.errors)
        finally:
            dash.close()
            token.undeclare()
