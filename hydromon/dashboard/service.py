"""A dashboard, whole: the fleet state, its source (the bus, or a recording) and the web server.

:func:`open_live` follows a bus session (``hydromon dashboard``, ``hydromon demo``);
:func:`open_recording` shows an MCAP recording in the same pages (its health and events, read
with ``hydromon.store.mcap_read``; ages are taken at the recording's end).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

from hydromon.contract import DEFAULT_NAMESPACE, check_namespace, rig_key_parts
from hydromon.dashboard.bus import BusFeed
from hydromon.dashboard.eventlog import EventLog
from hydromon.dashboard.fleet import Fleet
from hydromon.dashboard.server import WebServer
from hydromon.store.mcap_read import read_recording, read_summary

__all__ = ["Dashboard", "open_live", "open_recording", "default_events_path"]


def default_events_path(state_dir: str | os.PathLike | None, namespace: str) -> Path:
    """``STATE_DIR/dashboard-events-<ns>.jsonl`` (default state dir: ``$XDG_STATE_HOME/hydromon``,
    else ``~/.local/state/hydromon``)."""
    if state_dir is None:
        base = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
        state_dir = Path(base) / "hydromon"
    return Path(state_dir) / f"dashboard-events-{namespace.replace('/', '_')}.jsonl"


@dataclass
class Dashboard:
    fleet: Fleet
    web: WebServer | None
    feed: BusFeed | None = None
    foxglove: object | None = None  # a FoxgloveBridge

    @property
    def url(self) -> str | None:
        return None if self.web is None else self.web.url

    def close(self) -> None:
        if self.foxglove is not None:
            self.foxglove.close()
        if self.feed is not None:
            self.feed.close()
        if self.web is not None:
            self.web.close()
        self.fleet.events.close()

    def __enter__(self) -> Dashboard:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def open_live(session, *, namespace: str = DEFAULT_NAMESPACE, rigs: str = "*", host: str = "127.0.0.1",
              port: int | None = 8050, events_path=None, fallback_ranges=None, wait_s: float = 2.0,
              info: dict | None = None, foxglove_port: int | None = None) -> Dashboard:
    """A dashboard following ``session`` (open; not closed here), serving on ``host:port`` (None:
    no web server), and the Foxglove bridge on ``host:foxglove_port`` when given (0: a free port)."""
    from hydromon.dashboard.foxglove_bridge import FoxgloveBridge

    check_namespace(namespace)
    fleet = Fleet(EventLog(events_path), fallback_ranges=fallback_ranges)
    feed = BusFeed(session, fleet, namespace, rigs)
    dash = Dashboard(fleet, None, feed)
    try:
        if port is not None:
            dash.web = WebServer(fleet, host, port, on_tick=feed.on_tick,
                                 info={"source": "bus", "namespace": namespace, "rigs": rigs, **(info or {})})
        feed.start(wait_s)
        if dash.web is not None:
            dash.web.start()
        if foxglove_port is not None:
            # without a web server nobody ticks the state: the bridge does, at its fleet period
            tick = None if dash.web is not None else (lambda: feed.on_tick(fleet.tick(time.time())))
            dash.foxglove = FoxgloveBridge(session, fleet, namespace=namespace, rigs=rigs, host=host,
                                           port=foxglove_port, tick=tick).start()
    except BaseException:
        dash.close()
        raise
    return dash


def open_recording(path, *, host: str = "127.0.0.1", port: int = 8050, fallback_ranges=None) -> Dashboard:
    """A dashboard of the recording at ``path``: every rig's verdicts and events in it."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"--recording {str(path)!r}: no such file")
    start, end = _span(path)
    duration = max(end - start, 1e-3)
    fleet = Fleet(EventLog(None), fallback_ranges=fallback_ranges, live=False)
    spacing = max(1e-3, duration / 900)  # about 900 points per rig, however fast it was recorded
    fleet.history_shape = ((spacing, 1000), (max(spacing * 6, 6.0), 600))
    last, verdicts = start, 0
    for key, payload, log_ns, _pub in read_recording(path):
        last = max(last, log_ns / 1e9)  # its end, from every message (a file without a summary has no other)
        parts = rig_key_parts(key, None)
        if isinstance(parts, str) or parts[2] not in ("health", "event"):
            continue
        verdicts += parts[2] == "health"
        fleet.take_recorded(parts[1], parts[2], payload, log_ns / 1e9)
    # ages at the recording's end, not at its last verdict: a monitor that died before the
    # recorder did shows its rigs' verdicts as old as they were when the recording ended
    end = max(end, last)
    fleet.tick(end)
    web = WebServer(fleet, host, port, clock=lambda: end,
                    info={"source": "recording", "recording": str(path), "start": start, "end": end,
                          "verdicts": verdicts})
    web.start()
    return Dashboard(fleet, web)


def _span(path: Path) -> tuple[float, float]:
    """Log-time span of a recording [s] from its summary (0, 0 when it has none)."""
    try:
        stats = read_summary(path).statistics
    except Exception:  # no summary: the messages say
        return 0.0, 0.0
    if stats is None:
        return 0.0, 0.0
    return stats.message_start_time / 1e9, stats.message_end_time / 1e9
