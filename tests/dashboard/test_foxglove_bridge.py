"""The Foxglove bridge, spoken to as the Foxglove app does: a WebSocket client on the SDK's
subprotocol (``foxglove.sdk.v1``) against a bridge on a real zenoh session (loopback).

A peer publishes contract-valid config, health and events for the paper's five Table 4 rigs and
samples for one of them. The bridge must advertise the health and event channels with their JSON
Schemas (the contract's; health with its Foxglove-only ``bands``), a subscription must yield
messages that validate against them, samples must flow only while a client subscribes to them,
and the layout the package ships must name only topics the bridge advertises.
"""

from __future__ import annotations

import json
import struct
import threading
import time

import jsonschema
import orjson
import pytest
from websockets.sync.client import connect

from helpers import wait_for
from hydromon.bus.session import listening_session, open_session
from hydromon.contract import Event, Health, RigConfig, Sample
from hydromon.dashboard.foxglove_bridge import SUBPROTOCOL, channel_schemas
from hydromon.dashboard.foxglove_layout import DEFAULT_RIGS, SHIPPED, layout, layout_topics
from hydromon.dashboard.service import open_live
from monitor.ranges import Ranges


TRUE = {"table4-g1": "sub-health", "table4-g2": "health", "table4-g3": "fault", "table4-g4": "average",
        "table4-g5": "deterioration"}


def _health(rig: str, seq: int) -> bytes:
    grade = TRUE[rig]
    level = ("health", "sub-health", "average", "deterioration", "fault").index(grade)
    h = Health(seq=seq, t=seq / 100, grade=grade, level=level, confidence=0.8,
               params={"K_sv": 2.4e-4, "f_c": 12.0, "C_ip": 3e-11}, param_grades={"K_sv": grade, "f_c": "health"},
               status="ok", std_errors={"K_sv": 1e-6, "f_c": 0.5}, node="mon1", epoch=1)
    return h.model_dump_json().encode()


class Publisher:
    """Configs once, then health of every rig at 10 Hz and samples of table4-g1 at 100 Hz."""

    def __init__(self, session):
        self.session, self.stop = session, threading.Event()
        self.thread = threading.Thread(target=self.run, daemon=True)

    def run(self):
        for rig in DEFAULT_RIGS:
            self.session.put(f"hydro/rig/{rig}/config", RigConfig().model_dump_json().encode())
        seq = 0
        while not self.stop.wait(0.01):
            s = Sample(seq=seq, t=seq / 100, ug=0.1, x1=0.01, x3=5e6, x4=6e6, x5=1e-5)
            self.session.put("hydro/rig/table4-g1/sample", s.model_dump_json().encode())
            if seq % 10 == 0:
                for rig in DEFAULT_RIGS:
                    self.session.put(f"hydro/rig/{rig}/health", _health(rig, seq))
            seq += 1


class Client:
    def __init__(self, ws):
        self.ws = ws
        assert self.ws.subprotocol == SUBPROTOCOL
        self.channels: dict[str, dict] = {}
        self.server_info = None
        self.messages: dict[int, list] = {}

    def pump(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            try:
                m = self.ws.recv(timeout=left)
            except TimeoutError:
                return
            if isinstance(m, bytes):
                assert m[0] == 1, m[:1]
                sub, _ts = struct.unpack_from("<IQ", m, 1)
                self.messages.setdefault(sub, []).append(json.loads(m[13:]))
                continue
            msg = json.loads(m)
            if msg["op"] == "serverInfo":
                self.server_info = msg
            elif msg["op"] == "advertise":
                for ch in msg["channels"]:
                    self.channels[ch["topic"]] = ch

    def subscribe(self, sub_id: int, topic: str) -> None:
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": sub_id, "channelId":
                                                                        self.channels[topic]["id"]}]}))

    def unsubscribe(self, sub_id: int) -> None:
        self.ws.send(json.dumps({"op": "unsubscribe", "subscriptionIds": [sub_id]}))


def test_the_shipped_layout_is_the_generated_one():
    assert json.loads(SHIPPED.read_text()) == layout()


@pytest.mark.network
@pytest.mark.timeout(60)
def test_foxglove_clients_see_schemas_messages_and_samples_on_demand():
    with listening_session("peer") as (pub_session, ep), open_session("peer", connect=[ep]) as session:
        dash = open_live(session, port=None, foxglove_port=0, wait_s=0.5, fallback_ranges=Ranges.default())
        pub = Publisher(pub_session)
        try:
            bridge = dash.foxglove
            pub.thread.start()
            with connect(bridge.address, subprotocols=[SUBPROTOCOL], open_timeout=10) as ws:
                _as_the_foxglove_app(Client(ws), bridge, pub_session)
        finally:
            pub.stop.set()
            pub.thread.join(5)
            dash.close()


def _as_the_foxglove_app(client, bridge, pub_session) -> None:
    wanted = {f"hydro/rig/{r}/{leaf}" for r in DEFAULT_RIGS for leaf in ("health", "event", "config", "sample")}
    wanted.add("hydro/fleet")

    def advertised():
        client.pump(0.1)
        return wanted <= set(client.channels)

    wait_for(advertised, 15, "every rig's channels advertised")
    assert client.server_info is not None
    schemas = channel_schemas()
    contract = {"health": Health.model_json_schema(), "event": Event.model_json_schema(by_alias=True)}
    for topic, ch in client.channels.items():
        leaf = topic.rsplit("/", 1)[1]
        assert ch["encoding"] == "json" and ch["schemaEncoding"] == "jsonschema", ch
        schema = json.loads(ch["schema"])
        assert schema == schemas[leaf], topic
        if leaf in contract:
            assert ch["schemaName"] == f"hydromon.{leaf.capitalize()}"
            without_bands = {**schema, "properties": {k: v for k, v in schema["properties"].items()
                                                      if k != "bands"}}
            assert without_bands == contract[leaf], topic
    assert layout_topics(json.loads(SHIPPED.read_text())) <= set(client.channels)

    # samples only on demand
    assert bridge.sample_subs == {}
    client.subscribe(1, "hydro/rig/table4-g3/health")
    client.subscribe(2, "hydro/rig/table4-g3/event")
    client.subscribe(3, "hydro/rig/table4-g1/sample")
    client.subscribe(4, "hydro/fleet")
    client.subscribe(5, "hydro/rig/table4-g3/config")
    wait_for(lambda: set(bridge.sample_subs) == {"table4-g1"}, 5, "the sample subscription on the bus")
    time.sleep(0.3)
    ev = Event.model_validate({"seq": 5, "t": 0.05, "kind": "grade", "from": "deterioration", "to": "fault",
                               "reason": "valve gain -60 % of its baseline", "node": "mon1"})
    pub_session.put("hydro/rig/table4-g3/event", orjson.dumps(ev.model_dump(by_alias=True)))
    # payloads that are not the contract's: never shown (every message below validates against its schema)
    pub_session.put("hydro/rig/table4-g3/health", b'{"params":{},"grade":"<img src=x>","level":99,"confidence":7}')
    pub_session.put("hydro/rig/table4-g3/event", b'{"kind":"grade","to":"fault","reason":"forged, not an Event"}')
    pub_session.put("hydro/rig/table4-g3/config", b'{"A1": -1}')

    def got_all():
        client.pump(0.1)
        return all(len(client.messages.get(i, [])) >= n for i, n in ((1, 3), (2, 1), (3, 20), (4, 2)))

    wait_for(got_all, 15, "messages on every subscription")
    client.pump(0.5)  # what came after the forged payloads: none of them among it
    assert client.messages.get(5, []) == []  # the config channel's only message was the forged one
    for sub_id, topic in ((1, "hydro/rig/table4-g3/health"), (2, "hydro/rig/table4-g3/event"),
                          (3, "hydro/rig/table4-g1/sample"), (4, "hydro/fleet")):
        schema = json.loads(client.channels[topic]["schema"])
        for msg in client.messages[sub_id]:
            jsonschema.validate(msg, schema)
    h = client.messages[1][-1]
    assert h["grade"] == "fault"
    assert h["bands"]["K_sv"]["edges"] == list(Ranges.default().params["K_sv"].edges)
    assert h["bands"]["K_sv"]["lo"] == pytest.approx(2.4e-4 - 3e-6)
    assert client.messages[2][0]["to"] == "fault" and len(client.messages[2]) == 1
    fleet = client.messages[4][-1]
    assert {r["rig"] for r in fleet["rigs"]} == set(DEFAULT_RIGS)
    assert [r["rig"] for r in fleet["rigs"]] == ["table4-g3", "table4-g5", "table4-g4", "table4-g1", "table4-g2"]

    client.unsubscribe(3)
    wait_for(lambda: bridge.sample_subs == {}, 5, "the sample subscription undeclared")
