"""``hydromon demo``: the whole system in one process on an embedded zenoh session.

One peer session listens on a free ``tcp/127.0.0.1`` port (multicast scouting off, no
router), so other nodes on this machine may ``--connect`` to it; on it, in threads:

* the simulator node (:func:`hydromon.bus.sim.run_sim`) with the paper's five Table 4 rigs
  (or a fleet file),
* the monitor node (:func:`hydromon.bus.monitor.run_monitor`),
* the recorder (:func:`hydromon.bus.recorder.record`) writing ``DIR/demo-<UTC time>.mcap``,

and, in the calling thread, a table of the latest health of every rig fed by a subscriber
on ``<ns>/rig/*/health``: a ``rich.live.Live`` table on a terminal, a plain table every
few seconds otherwise. After ``duration`` [s of wall time] or ``stop_event`` it shuts down
in data-flow order (sim, then monitor, then recorder, each draining what is queued), so the
recording ends with the last verdicts, and returns a :class:`DemoResult`.
"""

from __future__ import annotations

import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import orjson
import zenoh

from contextlib import contextmanager

from hydromon.bus.connectivity import ConnectivityLog
from hydromon.bus.session import listening_session, make_config, open_session, summarize_config
from hydromon.contract import DEFAULT_NAMESPACE, check_namespace, parse_rig_key
from hydromon.store.fleetfile import FleetSpec, default_fleet, true_grade
from hydromon.report.demo import live_display, render_plain, render_rich
from hydromon.bus.inprocess import Worker, await_recorder_and_monitor

__all__ = ["DemoResult", "run_demo"]


@dataclass
class DemoResult:
    """What a demo run did: the recording, each rig's last health and its true grade."""

    endpoint: str
    recordings: list[Path] = field(default_factory=list)
    health: dict[str, dict] = field(default_factory=dict)  # rig id -> last health payload
    truth: dict[str, str | None] = field(default_factory=dict)
    counters: dict = field(default_factory=dict)
    samples: int = 0  # per rig, simulated
    recorded: int = 0  # messages in the recording

    @property
    def matches(self) -> int:
        return sum(1 for r, g in self.truth.items() if g is not None and self.health.get(r, {}).get("grade") == g)


def _recording_path(out_dir: Path) -> Path:
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    path = out_dir / f"demo-{stamp}.mcap"
    n = 2
    while path.exists():
        path = out_dir / f"demo-{stamp}-{n}.mcap"
        n += 1
    return path


@contextmanager
def _demo_session(zenoh_config=None):
    """:func:`_open_demo_session`, with the log of being cut off from the other nodes
    (:class:`~hydromon.bus.connectivity.ConnectivityLog`), stopped before the session closes."""
    with _open_demo_session(zenoh_config) as (session, endpoint):
        connectivity = ConnectivityLog(session, "demo")
        try:
            yield session, endpoint
        finally:
            connectivity.close()


@contextmanager
def _open_demo_session(zenoh_config=None):
    """``(session, endpoint)``: the demo's embedded session and where other nodes reach it. A peer
    on a free loopback port; with a zenoh configuration file, the file's session, on the file's
    listen (or connect) endpoints if it names some, else on a free loopback port too."""
    if zenoh_config is None:
        with listening_session("peer") as pair:
            yield pair
        return
    conf = make_config(None, (), (), False, zenoh_config)
    summary = summarize_config(conf)
    if summary.listen or summary.connect:
        with open_session(config=conf, config_file=zenoh_config) as session:
            yield session, (summary.listen or summary.connect)[0]
    else:
        with listening_session("router" if summary.mode == "router" else "peer", config_file=zenoh_config) as pair:
            yield pair


def run_demo(*, duration: float | None = 30.0, out_dir=".", rate: float = 1.0,
             namespace: str = DEFAULT_NAMESPACE, fleet: FleetSpec | None = None,
             stop_event: threading.Event | None = None, live: bool | None = None,
             plain_every: float = 3.0, stream=None, log=None, zenoh_config=None, attach=None) -> DemoResult:
    """Run sim, monitor and recorder on one embedded session; show the grades; return.

    Parameters
    ----------
    duration : float or None
        Wall time to run [s]; None = until ``stop_event``.
    out_dir : str or Path
        Directory of the recording (created if missing).
    rate : float
        Simulation speed relative to real time (0 = as fast as possible).
    fleet : FleetSpec or None
        The rigs (default: the paper's Table 4 rigs ``table4-g1`` .. ``table4-g5``).
    stop_event : threading.Event or None
        Set it (e.g. from a signal handler) to stop early.
    live : bool or None
        A ``rich.live.Live`` table (True) or a plain table every ``plain_every`` [s]
        (False); None = live if ``stream`` is a terminal.
    stream : text stream
        Where the table goes (default stdout); ``log`` gets progress lines (default stderr).
    zenoh_config : path or None
        A zenoh configuration file for the embedded session (:func:`_demo_session`).
    attach : callable or None
        ``attach(session, namespace) -> (close, lines)``, called once the monitor is up and before
        the rigs start: something else on the demo's session (the command line's dashboard);
        ``lines`` are printed on ``log`` and above the table, ``close()`` is called at the end.
    """
    from hydromon.engine.warm import warm_up
    from hydromon.engine.core import MonitorCore
    from hydromon.engine.watches import RateLimitedLog, RigWarningLog
    from hydromon.bus.monitor import run_monitor
    from hydromon.bus.recorder import record
    from hydromon.bus.sim import run_sim

    check_namespace(namespace)
    if duration is not None and not duration > 0:
        raise ValueError(f"duration {duration!r} must be > 0 s")
    if not rate >= 0:
        raise ValueError(f"rate {rate!r} must be >= 0")
    stream = stream or sys.stdout
    log = log or sys.stderr
    if live is None:
        live = stream.isatty()
    spec = fleet or default_fleet()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    stop = stop_event if stop_event is not None else threading.Event()
    health: dict[str, dict] = {}
    stop_sim, stop_mon, stop_rec = threading.Event(), threading.Event(), threading.Event()
    core = MonitorCore(namespace, on_reject=RateLimitedLog(), on_warning=RigWarningLog())
    path = _recording_path(out_dir)
    close_attached, lines = None, []

    warm_up()  # on a cold cache this compiles for about a minute: hydromon.cli.main says so then
    # on a free loopback port (another if it was taken before the session bound it)
    with _demo_session(zenoh_config) as (session, endpoint):
        result = DemoResult(endpoint=endpoint, truth={r.id: true_grade(r) for r in spec.rigs})
        sub = session.declare_subscriber(f"{namespace}/rig/*/health", zenoh.handlers.FifoChannel(100_000))

        def drain():
            while (m := sub.try_recv()) is not None:
                parsed = parse_rig_key(str(m.key_expr), namespace)
                if parsed is None:
                    continue
                try:
                    health[parsed[0]] = orjson.loads(m.payload.to_bytes())
                except orjson.JSONDecodeError:
                    pass

        rec = Worker("recorder", lambda: record(session, path, namespace=namespace, stop_event=stop_rec))
        mon = Worker("monitor", lambda: run_monitor(session, namespace=namespace, node_name="demo",
                                                     stop_event=stop_mon, core=core))
        sim = Worker("sim", lambda: run_sim(session, spec, namespace=namespace, rate=rate, stop_event=stop_sim))
        workers = (rec, mon, sim)
        try:
            rec.start()
            mon.start()
            await_recorder_and_monitor(session, namespace, "demo", rec, mon, "demo", stop)
            if attach is not None:
                close_attached, lines = attach(session, namespace)
                for line in lines:
                    print(f"hydromon demo: {line}", file=log, flush=True)
            sim.start()
            print(f"hydromon demo: {len(spec.rigs)} rig(s) at "
                  f"{'max speed' if rate == 0 else f'{rate:g}x real time'}, bus {endpoint}, recording {path}",
                  file=log, flush=True)
            deadline = None if duration is None else time.monotonic() + duration

            def done():
                return stop.is_set() or (deadline is not None and time.monotonic() >= deadline) or \
                    any(w.error is not None or (w.ident is not None and not w.is_alive()) for w in workers)

            title = f"hydromon demo - {namespace}/rig/*/health (Ctrl-C to stop)" + "".join(f"\n{x}" for x in lines)
            if live:
                with live_display(stream, render_rich(spec.ids, health, result.truth, title)) as update:
                    while not done():
                        stop.wait(0.25)
                        drain()
                        update(render_rich(spec.ids, health, result.truth, title))
            else:
                next_print = time.monotonic() + plain_every
                while not done():
                    stop.wait(0.1)
                    drain()
                    if time.monotonic() >= next_print:
                        next_print += plain_every
                        print("".join(f"{x}\n" for x in lines) + render_plain(spec.ids, health, result.truth) + "\n",
                              file=stream, flush=True)
        finally:
            # data-flow order: what the sim sent is graded, and the verdicts are recorded
            for ev, w in ((stop_sim, sim), (stop_mon, mon), (stop_rec, rec)):
                ev.set()
                if w.ident is not None:
                    w.join(60)
            drain()
            if close_attached is not None:
                close_attached()
        for w in workers:
            if w.error is not None:
                raise w.error
            if w.is_alive():
                raise RuntimeError(f"demo: the {w.name} thread did not stop")
    result.health = health
    result.counters = core.counters.as_dict()
    result.samples = sim.result.samples if sim.result is not None else 0
    if rec.result is not None:
        result.recordings = list(rec.result.files)
        result.recorded = rec.result.messages
    return result


