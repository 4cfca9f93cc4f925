"""``hydromon demo``: the whole system in one process on an embedded zenoh session.

One peer session listens on a free ``tcp/127.0.0.1`` port (multicast scouting off, no
router), so other nodes on this machine may ``--connect`` to it; on it, in threads:

* the simulator node (:func:`hydromon.simnode.run_sim`) with the paper's five Table 4 rigs
  (or a fleet file),
* the monitor node (:func:`hydromon.monitornode.run_monitor`),
* the recorder (:func:`hydromon.recorder.record`) writing ``DIR/demo-<UTC time>.mcap``,

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

from hydromon.bus import listening_session
from hydromon.contract import DEFAULT_NAMESPACE, _check_ns, parse_rig_key
from hydromon.fleetfile import FleetSpec, RigSpec, default_fleet
from hydromon.health_table import GRADE_STYLE, TABLE_PARAMS, fmt_value
from hydromon.inprocess import Worker, await_recorder_and_monitor

__all__ = ["DemoResult", "run_demo", "true_grade", "TABLE_PARAMS", "render_plain", "render_rich"]



def true_grade(rig: RigSpec) -> str | None:
    """The grade a simulated rig really has: its Table 4 group's paper grade, the grade of
    its severity, or None when unknown (plant overrides, or an undegraded Table 1 plant with
    overrides)."""
    from plant_sim.degradation import TABLE4_PAPER_GRADES, grade_of_severity

    if rig.params:
        return None
    if rig.table4 is not None:
        return TABLE4_PAPER_GRADES[rig.table4]
    if rig.severity is not None:
        return grade_of_severity(rig.severity)
    return "health"


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


def _rows(ids, health: dict, truth: dict):
    for rig in ids:
        h = health.get(rig)
        if h is None:
            yield [rig, "-", "-", "waiting", *["-"] * len(TABLE_PARAMS), "-", truth.get(rig) or "?"]
            continue
        yield [rig, h["grade"], f"{h['confidence']:.2f}", h["status"],
               *[fmt_value(h["params"].get(p)) for p in TABLE_PARAMS], f"{h['t']:.1f}", truth.get(rig) or "?"]


_HEAD = ["rig", "grade", "conf", "status", *TABLE_PARAMS, "t [s]", "true"]


def render_plain(ids, health: dict, truth: dict) -> str:
    """The table of the latest health as aligned plain text."""
    rows = [_HEAD, *_rows(ids, health, truth)]
    widths = [max(len(r[i]) for r in rows) for i in range(len(_HEAD))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows)


def render_rich(ids, health: dict, truth: dict, title: str = ""):
    """The table of the latest health as a ``rich.table.Table``."""
    from rich import box
    from rich.table import Table

    t = max((h["t"] for h in health.values()), default=0.0)
    table = Table(title=f"{title}\nrig time {t:.1f} s" if title else None, title_justify="left",
                  box=box.SIMPLE_HEAD, pad_edge=False, padding=(0, 1, 0, 0))
    for name in _HEAD[:-2]:  # rig time is in the title, the true grade in the closing summary
        table.add_column(name, justify="right" if name in (*TABLE_PARAMS, "conf") else "left",
                         no_wrap=name in ("rig", "grade", "status"))
    for row in _rows(ids, health, truth):
        style = GRADE_STYLE.get(row[1], "")
        row[1] = f"[{style}]{row[1]}[/]" if style else row[1]
        table.add_row(*row[:-2])
    return table


def _recording_path(out_dir: Path) -> Path:
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    path = out_dir / f"demo-{stamp}.mcap"
    n = 2
    while path.exists():
        path = out_dir / f"demo-{stamp}-{n}.mcap"
        n += 1
    return path


def run_demo(*, duration: float | None = 30.0, out_dir=".", rate: float = 1.0,
             namespace: str = DEFAULT_NAMESPACE, fleet: FleetSpec | None = None,
             stop_event: threading.Event | None = None, live: bool | None = None,
             plain_every: float = 3.0, stream=None, log=None) -> DemoResult:
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
    """
    from monitor.pipeline import warm_up
    from hydromon.monitornode import MonitorCore, RateLimitedLog, log_rig_warning, run_monitor
    from hydromon.recorder import record
    from hydromon.simnode import run_sim

    _check_ns(namespace)
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
    core = MonitorCore(namespace, on_reject=RateLimitedLog(), on_warning=log_rig_warning)
    path = _recording_path(out_dir)

    print("hydromon demo: loading the numerical kernels (compiled once on a fresh machine, "
          "about a minute)...", file=log, flush=True)
    warm_up()
    # on a free loopback port (another if it was taken before the session bound it)
    with listening_session("peer") as (session, endpoint):
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
            sim.start()
            print(f"hydromon demo: {len(spec.rigs)} rig(s) at "
                  f"{'max speed' if rate == 0 else f'{rate:g}x real time'}, bus {endpoint}, recording {path}",
                  file=log, flush=True)
            deadline = None if duration is None else time.monotonic() + duration

            def done():
                return stop.is_set() or (deadline is not None and time.monotonic() >= deadline) or \
                    any(w.error is not None or (w.ident is not None and not w.is_alive()) for w in workers)

            title = f"hydromon demo - {namespace}/rig/*/health (Ctrl-C to stop)"
            if live:
                from rich.console import Console
                from rich.live import Live

                console = Console(file=stream)
                with Live(render_rich(spec.ids, health, result.truth, title), console=console,
                          refresh_per_second=4, transient=False) as lv:
                    while not done():
                        stop.wait(0.25)
                        drain()
                        lv.update(render_rich(spec.ids, health, result.truth, title))
            else:
                next_print = time.monotonic() + plain_every
                while not done():
                    stop.wait(0.1)
                    drain()
                    if time.monotonic() >= next_print:
                        next_print += plain_every
                        print(render_plain(spec.ids, health, result.truth) + "\n", file=stream, flush=True)
        finally:
            # data-flow order: what the sim sent is graded, and the verdicts are recorded
            for ev, w in ((stop_sim, sim), (stop_mon, mon), (stop_rec, rec)):
                ev.set()
                if w.ident is not None:
                    w.join(60)
            drain()
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


def summary(result: DemoResult, ids) -> str:
    """The closing report: where the recording is, final grade next to the true grade."""
    lines = []
    for path in result.recordings:
        lines.append(f"recording: {path} ({result.recorded} messages)")
    head = ["rig", "final grade", "true grade", "status", "conf", ""]
    rows = [head]
    for rig in ids:
        h = result.health.get(rig, {})
        truth = result.truth.get(rig)
        mark = "" if truth is None or not h else ("ok" if h.get("grade") == truth else "MISMATCH")
        rows.append([rig, h.get("grade", "-"), truth or "?", h.get("status", "-"),
                     f"{h['confidence']:.2f}" if h else "-", mark])
    widths = [max(len(r[i]) for r in rows) for i in range(len(head))]
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
    known = sum(1 for g in result.truth.values() if g is not None)
    lines.append(f"{result.matches}/{known} rigs at their true grade after {result.samples} samples per rig")
    return "\n".join(lines)
