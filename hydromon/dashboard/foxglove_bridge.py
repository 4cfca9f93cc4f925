"""The bus in Foxglove, live: a Foxglove WebSocket server (the ``foxglove-sdk`` package, subprotocol
``foxglove.sdk.v1``) with one JSON-Schema channel per rig and leaf.

Topics are the bus keys, as in a recording, so one layout serves both:

* ``<ns>/rig/<id>/health``: the contract's ``Health`` schema with one more property, ``bands``
  (Foxglove only, not on the bus): per graded parameter its four band edges in grade order (or
  its fault threshold), its baseline and ``value -+ 3 SE`` as ``lo``/``hi``, so a Plot panel can
  draw the health bands beside the estimate;
* ``<ns>/rig/<id>/event`` and ``<ns>/rig/<id>/config``: the payloads as on the bus, with the
  contract's ``Event`` and ``RigConfig`` schemas;
* ``<ns>/rig/<id>/sample``: advertised for every known rig, but the bridge subscribes to a rig's
  samples on the bus only while a Foxglove client subscribes to that channel (100 per second per
  rig is more than a fleet view needs);
* ``<ns>/fleet``: twice a second, every rig's grade, level, status, confidence and flag, for a
  Table panel.

A channel is advertised when its rig is first heard of (health, config or event). Schema names
are those of the recordings' channels (``hydromon.Health``, ...).
"""

from __future__ import annotations

import json
import math
import threading
import time

import foxglove
import orjson
import zenoh
from pydantic import ValidationError

from hydromon.contract import DEFAULT_NAMESPACE, Event, Health, RigConfig, Sample, parse_rig_key, sample_key
from hydromon.dashboard.fleet import Fleet

__all__ = ["FoxgloveBridge", "channel_schemas", "BANDS_SCHEMA", "SUBPROTOCOL"]

SUBPROTOCOL = "foxglove.sdk.v1"
FLEET_EVERY_S = 0.5
BANDS_SCHEMA = {
    "type": "object",
    "description": "Foxglove only: per graded parameter its health band edges in grade order (health|sub-health, "
                   "sub-health|average, average|deterioration, deterioration|fault) or its fault threshold, the "
                   "rig's baseline, and the estimate -+ 3 standard errors (lo, hi), in the parameter's SI unit",
    "additionalProperties": {
        "type": "object",
        "properties": {
            "edges": {"anyOf": [{"type": "array", "items": {"type": "number"}, "minItems": 4, "maxItems": 4},
                                {"type": "null"}]},
            "threshold": {"anyOf": [{"type": "number"}, {"type": "null"}]},
            "baseline": {"anyOf": [{"type": "number"}, {"type": "null"}]},
            "lo": {"anyOf": [{"type": "number"}, {"type": "null"}]},
            "hi": {"anyOf": [{"type": "number"}, {"type": "null"}]},
        },
    },
}
FLEET_SCHEMA = {
    "title": "hydromon.Fleet", "type": "object", "additionalProperties": False,
    "description": "Every rig the bridge has heard of, the ones that need attention first.",
    "properties": {"rigs": {"type": "array", "items": {"type": "object", "properties": {
        "rig": {"type": "string"}, "grade": {"type": "string"},
        "level": {"anyOf": [{"type": "integer"}, {"type": "null"}]}, "status": {"type": "string"},
        "confidence": {"type": "number"}, "flag": {"anyOf": [{"type": "string"}, {"type": "null"}]},
        "why": {"type": "string"}}}},
        "counts": {"type": "object", "additionalProperties": {"type": "integer"}}},
    "required": ["rigs"],
}


def _valid(model, payload: bytes) -> bool:
    """Whether ``payload`` is a ``model`` (a contract payload): the bridge shows nothing else."""
    try:
        model.model_validate_json(payload)
    except ValidationError:
        return False
    return True


def channel_schemas() -> dict[str, dict]:
    """The JSON Schema of each leaf's channel (``fleet`` for ``<ns>/fleet``)."""
    health = Health.model_json_schema()
    health["properties"] = {**health["properties"], "bands": BANDS_SCHEMA}
    return {"health": health, "event": Event.model_json_schema(by_alias=True), "config": RigConfig.model_json_schema(),
            "sample": Sample.model_json_schema(), "fleet": FLEET_SCHEMA}


_NAMES = {"health": "hydromon.Health", "event": "hydromon.Event", "config": "hydromon.RigConfig",
          "sample": "hydromon.Sample", "fleet": "hydromon.Fleet"}


def _finite(v):
    return v if v is not None and math.isfinite(v) else None


def bands(h: dict, ranges) -> dict:
    """The ``bands`` of a health message (see the module's doc)."""
    out = {}
    graded = ranges.params if ranges is not None else {p: None for p in h.get("param_grades", {})}
    for name, pr in graded.items():
        v, se = h["params"].get(name), h.get("std_errors", {}).get(name)
        ok = v is not None and se is not None and math.isfinite(se)
        est = ranges.baseline.get(name) if ranges is not None else None
        out[name] = {"edges": list(pr.edges) if pr is not None and pr.edges is not None else None,
                     "threshold": pr.fault_threshold if pr is not None else None,
                     "baseline": est.value if est is not None else None,
                     "lo": _finite(v - 3 * se) if ok else None, "hi": _finite(v + 3 * se) if ok else None}
    return out


class FoxgloveBridge:
    """Serves the bus of ``session`` to Foxglove on ``host:port`` (port 0: a free one) until :meth:`close`.

    ``fleet`` is a dashboard's state on the same bus (``hydromon.dashboard.bus.BusFeed`` feeds it):
    its ranges give the bands and its rows the fleet table. ``tick`` (optional) is called every
    fleet period: the push period of a bridge without a web server, which runs no ticks of its own.
    """

    def __init__(self, session: zenoh.Session, fleet: Fleet, *, namespace: str = DEFAULT_NAMESPACE,
                 rigs: str = "*", host: str = "127.0.0.1", port: int = 8765, tick=None):
        self.session, self.ns, self.rigs = session, namespace, rigs
        self.fleet, self.tick = fleet, tick
        self.context = foxglove.Context()
        self.schemas = channel_schemas()
        self.channels: dict[str, foxglove.Channel] = {}
        self.sample_subs: dict[str, object] = {}    # rig -> zenoh subscriber of its samples
        self._subscribers: dict[int, set] = {}      # channel id -> client ids
        self._by_id: dict[int, str] = {}            # channel id -> topic
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._decls = []
        self.fleet_channel = self._channel(f"{namespace}/fleet", "fleet")
        try:
            self.server = foxglove.start_server(name="hydromon", host=host, port=port, context=self.context,
                                                server_listener=self)
        except RuntimeError as exc:  # the SDK's FoxgloveError, e.g. the port taken: one line, as for the web server
            reason = str(exc).removeprefix("FoxgloveError: ")
            raise OSError(f"cannot serve Foxglove on {host}:{port}: {reason}") from None
        self.port = self.server.port
        self.address = f"ws://{host}:{self.port}"
        self._thread = threading.Thread(target=self._fleet_loop, name="foxglove-fleet", daemon=True)

    # -- channels ---------------------------------------------------------------------------------
    def _channel(self, topic: str, leaf: str) -> foxglove.Channel:
        ch = self.channels.get(topic)
        if ch is None:
            with self._lock:
                ch = self.channels.get(topic)
                if ch is None:
                    schema = foxglove.Schema(name=_NAMES[leaf], encoding="jsonschema",
                                             data=json.dumps(self.schemas[leaf]).encode())
                    ch = foxglove.Channel(topic, schema=schema, message_encoding="json", context=self.context)
                    self.channels[topic] = ch
                    self._by_id[ch.id()] = topic
        return ch

    def _rig_known(self, rig: str) -> None:
        if f"{self.ns}/rig/{rig}/health" not in self.channels:
            for leaf in ("health", "event", "config", "sample"):
                self._channel(f"{self.ns}/rig/{rig}/{leaf}", leaf)

    # -- the bus ----------------------------------------------------------------------------------
    def start(self) -> FoxgloveBridge:
        ns = self.ns

        def on_message(sample: zenoh.Sample) -> None:
            key = str(sample.key_expr)
            parsed = parse_rig_key(key, ns)
            if parsed is None:
                return
            rig, leaf = parsed
            self._rig_known(rig)
            payload = sample.payload.to_bytes()
            if leaf == "health":
                self._log_health(key, rig, payload)
            elif leaf in ("event", "config"):
                ch = self.channels[key]
                if ch.has_sinks() and _valid(Event if leaf == "event" else RigConfig, payload):
                    ch.log(payload, log_time=time.time_ns())

        for leaf in ("health", "event", "config"):
            self._decls.append(self.session.declare_subscriber(f"{ns}/rig/{self.rigs}/{leaf}", on_message))
        # rigs that published their config before the bridge came up (the sim node answers)
        threading.Thread(target=self._ask_configs, args=(on_message,), daemon=True).start()
        self._thread.start()
        return self

    def _ask_configs(self, on_message) -> None:
        try:
            for reply in self.session.get(f"{self.ns}/rig/{self.rigs}/config", timeout=2.0):
                if reply.ok is not None:
                    on_message(reply.ok)
        except zenoh.ZError:
            pass

    def _log_health(self, key: str, rig: str, payload: bytes) -> None:
        ch = self.channels[key]
        if not ch.has_sinks():
            return
        try:
            valid = Health.model_validate_json(payload)
        except ValidationError:
            return  # not a contract payload: the dashboard counts it; Foxglove is not shown it
        # as on the dashboard's pages: not a verdict of an older start of the rig's monitor, nor of
        # a node that is not up or not the rig's (``engine.board.Board.shown``); the pages' own
        # handling of it (under the fleet's lock) decides whose verdicts the rig's are
        with self.fleet.lock:
            if not self.fleet.board.shown(rig, valid.node, valid.epoch):
                return
        h = orjson.loads(payload)
        h["bands"] = bands(h, self.fleet.ranges_for(rig))
        ch.log(orjson.dumps(h), log_time=time.time_ns())

    def _fleet_loop(self) -> None:
        while not self._stop.wait(FLEET_EVERY_S):
            if self.tick is not None:
                self.tick()
            snap = self.fleet.fleet_snapshot(time.time())
            rows = [{"rig": r["rig"], "grade": r["grade"], "level": r["level"], "status": r["status"],
                     "confidence": r["confidence"], "flag": r["flag"], "why": "; ".join(r["why"])}
                    for r in snap["rows"]]
            for r in rows:
                self._rig_known(r["rig"])
            counts = {k: v for k, v in snap["counts"]["grades"].items()}
            self.fleet_channel.log(orjson.dumps({"rigs": rows, "counts": counts}), log_time=time.time_ns())

    # -- the Foxglove clients (foxglove.websocket.ServerListener) ------------------------------------
    def on_subscribe(self, client, channel) -> None:
        topic = self._by_id.get(channel.id)
        with self._lock:
            self._subscribers.setdefault(channel.id, set()).add(client.id)
        if topic is not None and topic.endswith("/sample"):
            rig = topic.split("/")[-2]
            with self._lock:
                if rig not in self.sample_subs:
                    ch = self.channels[topic]
                    self.sample_subs[rig] = self.session.declare_subscriber(
                        sample_key(rig, self.ns), lambda s: ch.log(s.payload.to_bytes(), log_time=time.time_ns()))

    def on_unsubscribe(self, client, channel) -> None:
        topic = self._by_id.get(channel.id)
        with self._lock:
            subs = self._subscribers.get(channel.id, set())
            subs.discard(client.id)
            left = not subs
        if left and topic is not None and topic.endswith("/sample"):
            rig = topic.split("/")[-2]
            with self._lock:
                sub = self.sample_subs.pop(rig, None)
            if sub is not None:
                try:
                    sub.undeclare()
                except zenoh.ZError:
                    pass

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(5)
        for d in [*self._decls, *self.sample_subs.values()]:
            try:
                d.undeclare()
            except zenoh.ZError:
                pass
        self.sample_subs.clear()
        self.server.stop()
