"""The dashboard's web application (Starlette): three pages, their data, and the push channel.

Pages are static files of this package (``static/``): HTML with no data in it, scripts that ask
for their data over a WebSocket (``/ws?view=fleet|events|rig&rig=ID``: a snapshot first, then
what changed every push period) and put every text in the page with ``textContent``, never as
markup. Every response carries a Content-Security-Policy that allows scripts, styles and
connections from this server only. Bound to loopback, the server answers only requests whose
``Host`` is a loopback name (a web page elsewhere cannot reach it through DNS rebinding), and a
WebSocket or an acknowledgement from a page of another origin is refused.

Read-only towards the rigs: nothing here publishes on the bus. The one thing a person writes is
an acknowledgement of an event (``POST /api/events/{id}/ack``), kept in the dashboard's event log.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from pathlib import Path
from urllib.parse import urlsplit

import orjson
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, PlainTextResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from hydromon.contract import valid_rig_id
from hydromon.dashboard.eventlog import AlreadyAcknowledged
from hydromon.dashboard.fleet import Fleet, Tick

__all__ = ["build_app", "Hub", "CSP", "STATIC", "PUSH_S"]

STATIC = Path(__file__).with_name("static")
PUSH_S = 0.25
"""Push period [s]: what changed is sent to the browsers four times a second."""
CSP = ("default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data:; connect-src 'self'; "
       "font-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'")
_HEADERS = [(b"content-security-policy", CSP.encode()), (b"x-content-type-options", b"nosniff"),
            (b"referrer-policy", b"no-referrer"), (b"x-frame-options", b"DENY")]
LOOPBACK_NAMES = {"127.0.0.1", "localhost", "::1", "[::1]"}
SEND_TIMEOUT_S = 2.0


def _host_name(host: str) -> str:
    if host.startswith("["):
        return host[: host.find("]") + 1]
    return host.rsplit(":", 1)[0] if host.count(":") == 1 else host


class _Guard:
    """ASGI middleware: security headers on every response; on a loopback server, only loopback
    ``Host`` names."""

    def __init__(self, app, loopback_only: bool):
        self.app, self.loopback_only = app, loopback_only

    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        if self.loopback_only:
            host = dict(scope["headers"]).get(b"host", b"").decode("latin-1")
            if _host_name(host) not in LOOPBACK_NAMES:
                if scope["type"] == "http":
                    return await PlainTextResponse("unknown host", 421)(scope, receive, send)
                return await send({"type": "websocket.close", "code": 1008})

        async def with_headers(message):
            if message["type"] == "http.response.start":
                message = {**message, "headers": [*message.get("headers", []), *_HEADERS]}
            await send(message)

        return await self.app(scope, receive, with_headers)


def _same_origin(headers) -> bool:
    """A request without ``Origin`` (not from a page), or from a page of this server."""
    origin = headers.get("origin")
    return origin is None or urlsplit(origin).netloc == headers.get("host")


class Hub:
    """The open pages, each with its view, and the push loop that sends them what changed."""

    def __init__(self, fleet: Fleet, on_tick=None, clock=time.time):
        self.fleet, self.on_tick, self.clock = fleet, on_tick, clock
        self.clients: dict[WebSocket, tuple[str, str | None]] = {}

    def watched(self) -> set[str]:
        return {rig for view, rig in self.clients.values() if view == "rig" and rig is not None}

    def snapshot(self, view: str, rig: str | None) -> dict:
        now = self.clock()
        if view == "fleet":
            return self.fleet.fleet_snapshot(now)
        if view == "rig":
            return self.fleet.rig_snapshot(rig, now)
        return {"type": "events", "now": now, "events": self.fleet.events.recent(1000), "live": self.fleet.live}

    def messages(self, tick: Tick, view: str, rig: str | None) -> dict | None:
        if view == "fleet":
            return {"type": "fleet-delta", "now": tick.now, "rows": tick.rows, "counts": tick.counts}
        if view == "events":
            return {"type": "events-delta", "now": tick.now, "events": tick.events} if tick.events else None
        if rig in tick.resnap:  # its first verdict or new ranges: the page is drawn anew
            return self.fleet.rig_snapshot(rig, tick.now)
        row = next((r for r in tick.rows if r["rig"] == rig), None)
        events = [e for e in tick.events if e.get("rig") == rig]
        return {"type": "rig-delta", "now": tick.now, "row": row, "points": tick.points.get(rig), "events": events}

    async def broadcast(self, pick) -> None:
        sends = []
        for ws, (view, rig) in list(self.clients.items()):
            msg = pick(view, rig)
            if msg is not None:
                sends.append(self._send(ws, orjson.dumps(msg).decode()))
        if sends:
            await asyncio.gather(*sends)

    async def _send(self, ws: WebSocket, text: str) -> None:
        try:
            await asyncio.wait_for(ws.send_text(text), SEND_TIMEOUT_S)
        except Exception:  # a page that went away or cannot keep up: it reconnects and gets a snapshot
            self.clients.pop(ws, None)
            with contextlib.suppress(Exception):
                await ws.close()

    async def run(self, stop: asyncio.Event) -> None:
        loop = asyncio.get_running_loop()
        while not stop.is_set():
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(stop.wait(), PUSH_S)
            tick = await loop.run_in_executor(None, self.fleet.tick, self.clock(), self.watched())
            if self.on_tick is not None:
                self.on_tick(tick)
            await self.broadcast(lambda view, rig: self.messages(tick, view, rig))


def build_app(fleet: Fleet, *, loopback_only: bool = True, on_tick=None, info: dict | None = None,
              clock=time.time) -> Starlette:
    """The ASGI app serving ``fleet``; ``on_tick(tick)`` is called every push period (the bus
    side asks for ranges there); ``info`` is shown on the pages (bus, recording); ``clock`` is
    the time the ages are taken at (a recording's: its end)."""
    hub = Hub(fleet, on_tick, clock)
    info = dict(info or {})

    def page(name: str):
        async def handler(request: Request) -> Response:
            rig = request.path_params.get("rig")
            if rig is not None and not valid_rig_id(rig):
                return PlainTextResponse("not a rig id", 404)
            return FileResponse(STATIC / name, headers={"cache-control": "no-cache"})
        return handler

    async def api_fleet(request: Request) -> Response:
        return Response(orjson.dumps(fleet.fleet_snapshot(clock())), media_type="application/json")

    async def api_rig(request: Request) -> Response:
        rig = request.path_params["rig"]
        if not valid_rig_id(rig):
            return PlainTextResponse("not a rig id", 404)
        return Response(orjson.dumps(fleet.rig_snapshot(rig, clock())), media_type="application/json")

    async def api_events(request: Request) -> Response:
        return Response(orjson.dumps({"events": fleet.events.recent(1000)}), media_type="application/json")

    async def api_info(request: Request) -> Response:
        return JSONResponse(info)

    async def ack(request: Request) -> Response:
        if not _same_origin(request.headers):
            return PlainTextResponse("cross-origin request refused", 403)
        if request.headers.get("content-type", "").split(";")[0].strip() != "application/json":
            return PlainTextResponse("expected application/json", 415)
        try:
            body = orjson.loads(await request.body())
            ev = fleet.events.ack(int(request.path_params["event_id"]), body.get("comment", ""),
                                  body.get("by", ""), time.time())
        except KeyError:
            return PlainTextResponse("no such event", 404)
        except AlreadyAcknowledged as exc:
            return PlainTextResponse(str(exc), 409)
        except (ValueError, TypeError, AttributeError, orjson.JSONDecodeError) as exc:
            return PlainTextResponse(f"bad acknowledgement: {exc}", 400)
        await hub.broadcast(lambda view, rig: {"type": "ack", "event": ev}
                            if view == "events" or (view == "rig" and rig == ev.get("rig")) else None)
        return Response(orjson.dumps(ev), media_type="application/json")

    async def ws_endpoint(ws: WebSocket) -> None:
        view, rig = ws.query_params.get("view", "fleet"), ws.query_params.get("rig")
        if not _same_origin(ws.headers) or view not in ("fleet", "rig", "events") or \
                (view == "rig" and not valid_rig_id(rig or "")):
            await ws.close(code=1008)
            return
        await ws.accept()
        await ws.send_text(orjson.dumps({**hub.snapshot(view, rig), "info": info}).decode())
        hub.clients[ws] = (view, rig)
        try:
            while True:  # the pages send nothing; this notices when one goes
                await ws.receive_text()
        except WebSocketDisconnect:
            pass
        finally:
            hub.clients.pop(ws, None)

    @contextlib.asynccontextmanager
    async def lifespan(app):
        stop = asyncio.Event()
        task = asyncio.create_task(hub.run(stop))
        try:
            yield
        finally:
            stop.set()
            await task

    routes = [
        Route("/", page("fleet.html")),
        Route("/rig/{rig}", page("rig.html")),
        Route("/events", page("events.html")),
        Route("/api/fleet", api_fleet),
        Route("/api/rig/{rig}", api_rig),
        Route("/api/events", api_events),
        Route("/api/info", api_info),
        Route("/api/events/{event_id:int}/ack", ack, methods=["POST"]),
        WebSocketRoute("/ws", ws_endpoint),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ]
    app = Starlette(routes=routes, lifespan=lifespan)
    app.state.hub = hub
    return _Guard(app, loopback_only)
