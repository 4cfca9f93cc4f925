"""Golden recordings: small MCAP files made live, with the health they must replay to.

Each golden in :data:`GOLDENS` is made by the real nodes, in one process, on one embedded
zenoh session (multicast scouting off, no endpoints): the recorder
(:func:`hydromon.bus.recorder.record`) and the monitor (:func:`hydromon.bus.monitor.run_monitor`)
come up first, then the simulator node (:class:`hydromon.bus.sim.SimNode`) publishes the
rigs, segment by segment. A segment may be preceded by a dropout (rig time simulated but
not published: the monitor sees a seq gap) or be a restart (a fresh simulation, seq from
0 again). Shutdown goes in data-flow order (sim, monitor, recorder, each draining what is
queued), so the recording holds every sample, config and verdict.

Beside ``recordings/<name>.mcap`` goes ``<name>.health.jsonl``: the health messages stored
in the recording, in order, one ``{"key": ..., "health": {...}}`` line each
(:func:`hydromon.store.replay.health_jsonl`, payload bytes kept). ``tests/store/test_goldens.py``
checks on every run that a direct replay of each recording gives those messages byte for
byte. The monitor grades with a growing window (its estimators keep everything: no
``--memory``), which is ``replay --direct``'s default too; the live ``hydromon monitor``'s
default is 60 s (``hydromon.cli.memory.LIVE_MEMORY_S``). The health is a function of the
published samples only (the monitor core has no clock), so regenerating gives byte-identical
``.health.jsonl`` files as long as the numerics do not change; the ``.mcap`` files differ in their log times (wall clock).

When a change of the monitor's numerics changes the health, regenerate everything with::

    python -m hydromon.tools.goldens --update

and commit ``recordings/`` (``--update NAME ...`` regenerates only those, a new golden for one). Without ``--update`` the command checks the committed files.
"""

from __future__ import annotations

if __name__ == "__main__":  # run as a program: numba's cache is set before any kernel is imported
    from hydromon.tools import jitcache

    jitcache.configure()

import argparse  # noqa: E402
import hashlib
import os
import sys
import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path

import orjson

from hydromon.contract import DEFAULT_NAMESPACE
from hydromon.store.fleetfile import FleetSpec, RigSpec, default_fleet
from hydromon.bus.inprocess import Worker, await_recorder_and_monitor

__all__ = ["Segment", "Golden", "GOLDENS", "RECORDINGS_DIR", "MadeGolden", "make_golden", "write_goldens", "made_from_files",
           "stored_health", "read_health_jsonl", "check_golden", "true_grades", "main"]

RECORDINGS_DIR = Path(__file__).resolve().parents[2] / "recordings"
"""``recordings/`` at the top of the repository."""

_NODE = "goldens"


@dataclass(frozen=True)
class Segment:
    """One stretch of a golden's simulation.

    Attributes
    ----------
    seconds : float
        Rig time published [s].
    skip : float
        Rig time simulated but not published just before this segment [s] (a dropout:
        the monitor sees a gap in seq).
    restart : bool
        Start a fresh simulation of the fleet (seq from 0: the monitor sees a restart).
    """

    seconds: float
    skip: float = 0.0
    restart: bool = False


@dataclass(frozen=True)
class Golden:
    """A golden recording: its file name stem, the simulated fleet, the segments, a note, and
    ``frame`` N when the sim publishes frames of N samples (None: one message a sample)."""

    name: str
    fleet: FleetSpec
    segments: tuple[Segment, ...]
    about: str
    frame: int | None = None

    @property
    def mcap(self) -> str:
        return f"{self.name}.mcap"

    @property
    def health_file(self) -> str:
        return f"{self.name}.health.jsonl"


GOLDENS: tuple[Golden, ...] = (
    Golden("table4-clean", default_fleet(), (Segment(10.0),),
           "the paper's five Table 4 rigs table4-g1..g5, paper-var input, noise-free, 10 s"),
    Golden("table4-realistic", default_fleet(noise="realistic", seed=1), (Segment(10.0),),
           "the same five rigs with realistic sensor noise (x1 5 um, x3/x4 5 kPa, x5 0.5 um rms; fleet seed 1), 10 s"),
    Golden("gap-restart", FleetSpec(rigs=[RigSpec(id="table4-g4", table4=4)]),
           (Segment(5.0), Segment(5.0, skip=0.5), Segment(6.0, restart=True)),
           "one rig (Table 4 group 4, noise-free): 5 s, a 0.5 s dropout (seq gap of 50), 5 s, "
           "then the rig restarts (seq from 0) and runs 6 s"),
    Golden("table4-frames", FleetSpec(seed=1, rigs=default_fleet(noise="realistic", seed=1).rigs[:2]),
           (Segment(5.0),),
           "the first two rigs of table4-realistic (table4-g1, g2), published as frames of 10 samples, 5 s: "
           "each rig's health is that of its first 5 s in table4-realistic, byte for byte", frame=10),
)
"""The committed golden recordings, made by ``python -m hydromon.tools.goldens --update``.

10 s of rig time (the paper's identification run length; every rig is at its true grade
from 3.5 s on): 20 s would double the files, past the ~2 MB the repository can carry.
"""


def true_grades(golden: Golden) -> dict[str, str | None]:
    """Rig id -> the grade the rig really has (its Table 4 group's paper grade)."""
    from hydromon.store.fleetfile import true_grade

    return {r.id: true_grade(r) for r in golden.fleet.rigs}


@dataclass
class MadeGolden:
    """What :func:`make_golden` produced: the recording, its health and the node counters."""

    path: Path
    health: list[tuple[str, bytes]]      # health messages stored in the recording, in order
    counters: dict                       # the live monitor's counters
    samples: int                         # samples published, all rigs
    recorded: int                        # messages in the recording
    final: dict[str, str] = field(default_factory=dict)  # rig id -> last grade


def make_golden(golden: Golden, path, *, rate: float = 20.0, namespace: str = DEFAULT_NAMESPACE) -> MadeGolden:
    """Run sim, monitor and recorder live on one embedded session; record to ``path``.

    Parameters
    ----------
    path : str or Path
        The ``.mcap`` to write (must not exist).
    rate : float
        Simulation speed relative to real time (0 = as fast as possible).

    Raises RuntimeError if a node failed or the recording is not complete (a lost sample
    or verdict would make the golden meaningless).
    """
    import zenoh

    from hydromon.bus.session import open_session
    from hydromon.engine.core import MonitorCore
    from hydromon.engine.watches import RateLimitedLog
    from hydromon.bus.monitor import run_monitor
    from hydromon.bus.recorder import record
    from hydromon.bus.sim import SimNode

    path = Path(path)
    core = MonitorCore(namespace, on_reject=RateLimitedLog())
    stop_mon, stop_rec = threading.Event(), threading.Event()
    published = 0
    with open_session("peer", multicast=False) as session:
        rec = Worker("recorder", lambda: record(session, path, namespace=namespace, stop_event=stop_rec))
        mon = Worker("monitor", lambda: run_monitor(session, namespace=namespace, node_name=_NODE,
                                                     stop_event=stop_mon, core=core,
                                                     stale_after_s=None))  # clock-driven: not golden
        try:
            rec.start()
            mon.start()
            await_recorder_and_monitor(session, namespace, _NODE, rec, mon, "goldens")
            fleet = None
            for seg in golden.segments:
                if fleet is None or seg.restart:
                    fleet = golden.fleet.build()
                if seg.skip > 0:
                    fleet.step(int(round(seg.skip / fleet.h)))  # simulated, never published
                node = SimNode(session, golden.fleet.ids, fleet, namespace=namespace, rate=rate,
                               congestion=zenoh.CongestionControl.BLOCK, frame=golden.frame)
                stats = node.run(duration=seg.seconds)
                published += stats.samples * len(golden.fleet.ids)  # samples, one a message or many a frame
        finally:
            # data-flow order: every sample is graded, every verdict recorded
            for ev, w in ((stop_mon, mon), (stop_rec, rec)):
                ev.set()
                if w.ident is not None:
                    w.join(120)
    for w in (mon, rec):
        if w.error is not None:
            raise RuntimeError(f"goldens: the {w.name} failed: {w.error!r}") from w.error
        if w.is_alive():
            raise RuntimeError(f"goldens: the {w.name} thread did not stop")
    health = stored_health(path)
    c = core.counters
    if c.accepted != published or c.rejected_total or c.dropped_seq:
        raise RuntimeError(f"goldens: {golden.name}: the monitor took {c.accepted} of {published} samples "
                           f"(counters {c.as_dict()})")
    if len(health) != c.health:
        raise RuntimeError(f"goldens: {golden.name}: the recording holds {len(health)} of the monitor's "
                           f"{c.health} verdicts")
    final = {}
    for key, payload in health:
        final[key.split("/")[-2]] = orjson.loads(payload)["grade"]
    return MadeGolden(path=path, health=health, counters=c.as_dict(), samples=published,
                      recorded=rec.result.messages, final=final)


def stored_health(path) -> list[tuple[str, bytes]]:
    """The health messages ``[(key, payload)]`` stored in a recording, in log-time order."""
    from hydromon.store.mcap_read import read_recording

    return [(k, p) for k, p, _, _ in read_recording(path) if k.endswith("/health")]


def read_health_jsonl(path) -> list[tuple[str, bytes]]:
    """``[(key, payload)]`` from a ``.health.jsonl`` file; the inverse of ``health_jsonl``
    (payload bytes exactly as written)."""
    out = []
    prefix, mid = b'{"key":"', b'","health":'
    for n, line in enumerate(Path(path).read_bytes().splitlines(), 1):
        head, sep, rest = line.partition(mid)
        if not head.startswith(prefix) or not sep or not rest.endswith(b"}"):
            raise ValueError(f"{path}:{n}: not a health JSON line")
        out.append((head[len(prefix):].decode(), rest[:-1]))
    return out


def check_golden(golden: Golden, directory=RECORDINGS_DIR) -> list[str]:
    """Problems of one committed golden (empty if it is right): the direct replay, the
    stored health and the ``.health.jsonl`` file must agree, byte for byte."""
    from hydromon.store.replay import health_jsonl, replay_direct

    directory = Path(directory)
    mcap, jsonl = directory / golden.mcap, directory / golden.health_file
    missing = [str(p) for p in (mcap, jsonl) if not p.exists()]
    if missing:
        return [f"missing {', '.join(missing)}"]
    stored = stored_health(mcap)
    replayed, _ = replay_direct(mcap)
    problems = []
    if replayed != stored:
        problems.append(f"{golden.mcap}: a direct replay gives {len(replayed)} health messages that differ "
                        f"from the {len(stored)} stored in it")
    if jsonl.read_bytes() != b"".join(health_jsonl(stored)):
        problems.append(f"{golden.health_file} differs from the health stored in {golden.mcap}")
    return problems


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def _readme(made: dict[str, MadeGolden], rate: float) -> str:
    lines = [
        "# Golden recordings",
        "",
        "Generated by `python -m hydromon.tools.goldens --update` (this file too: edit",
        "`hydromon/tools/goldens.py`, not this file). Each `<name>.mcap` was recorded live: on one",
        "embedded zenoh session the recorder (`hydromon.bus.recorder.record`) and the monitor",
        "(`hydromon.bus.monitor.run_monitor`) came up first, then the simulator node",
        "(`hydromon.bus.sim.SimNode`) published the rigs at",
        f"{rate:g}x real time; the recording holds the rigs' configs, samples and the monitor's verdicts.",
        "`<name>.health.jsonl` holds the health messages stored in the recording, in order, as",
        "`hydromon replay FILE --direct` prints them. `tests/store/test_goldens.py` checks that a direct",
        "replay of each recording gives exactly those messages (byte for byte) and that each rig",
        "ends at its true grade.",
        "",
        "If a change of the monitor's numerics changes the health, the test fails; if the change is",
        "intended, run `python -m hydromon.tools.goldens --update` and commit `recordings/`. The",
        "`.health.jsonl` files are byte-identical from one regeneration to the next (health depends",
        "on the samples only); the `.mcap` files differ in their log times (wall clock).",
        "",
        "| recording | what | samples | verdicts | final grade of each rig (true grade if different) |",
        "| --- | --- | --- | --- | --- |",
    ]
    for g in GOLDENS:
        m = made[g.name]
        truth = true_grades(g)
        grades = ", ".join(f"{r} {m.final.get(r)}" + (f" (true: {truth[r]})" if m.final.get(r) != truth[r] else "")
                           for r in g.fleet.ids)
        c = m.counters
        extra = []
        if c["gaps"]:
            extra.append(f"{c['gaps']} gap ({c['missing']} samples missing)")
        if c["restarts"]:
            extra.append(f"{c['restarts']} restart")
        what = g.about + (f"; the monitor saw {', '.join(extra)}" if extra else "")
        lines.append(f"| `{g.mcap}` | {what} | {m.samples} | {len(m.health)} | {grades} |")
    lines += ["", "Segments (rig time): " + "; ".join(
        f"`{g.name}`: " + ", ".join(
            f"{s.seconds:g} s" + (f" after a {s.skip:g} s dropout" if s.skip else "")
            + (" after a restart" if s.restart else "") for s in g.segments) for g in GOLDENS), ""]
    return "\n".join(lines)


def made_from_files(golden: Golden, directory=RECORDINGS_DIR) -> MadeGolden:
    """What :func:`make_golden` said of a golden already in ``directory``, from its files (a
    direct replay of the recording)."""
    from hydromon.store.mcap_read import read_recording
    from hydromon.store.replay import replay_direct

    path = Path(directory) / golden.mcap
    health = stored_health(path)
    _, core = replay_direct(path)
    final = {key.split("/")[-2]: orjson.loads(payload)["grade"] for key, payload in health}
    return MadeGolden(path=path, health=health, counters=core.counters.as_dict(), samples=core.counters.accepted,
                      recorded=sum(1 for _ in read_recording(path)), final=final)


def write_goldens(directory=RECORDINGS_DIR, *, rate: float = 20.0, attempts: int = 3, log=sys.stderr,
                  names=None) -> dict:
    """Regenerate the goldens of :data:`GOLDENS` named in ``names`` (None: all) and the README
    into ``directory`` (the others are read from their files).

    Each recording is made in a temporary file, checked (complete, direct replay equal to
    the stored health) and only then moved over the old one. Returns name -> MadeGolden.
    """
    from hydromon.store.replay import health_jsonl, replay_direct

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    unknown = set(names or ()) - {g.name for g in GOLDENS}
    if unknown:
        raise ValueError(f"no golden named {', '.join(sorted(unknown))} (there are {', '.join(g.name for g in GOLDENS)})")
    made: dict[str, MadeGolden] = {g.name: made_from_files(g, directory) for g in GOLDENS
                                   if names and g.name not in names}
    for g in GOLDENS:
        if g.name in made:
            continue
        last_error = None
        for attempt in range(1, attempts + 1):
            with tempfile.TemporaryDirectory(dir=directory, prefix=".goldens-") as tmp:
                try:
                    m = make_golden(g, Path(tmp) / g.mcap, rate=rate)
                    replayed, _ = replay_direct(m.path)
                    if replayed != m.health:
                        raise RuntimeError(f"goldens: {g.name}: a direct replay differs from the live verdicts")
                except RuntimeError as exc:
                    last_error = exc
                    print(f"goldens: {g.name}: attempt {attempt} failed: {exc}", file=log)
                    continue
                jsonl = b"".join(health_jsonl(m.health))
                os.replace(m.path, directory / g.mcap)
                (directory / g.health_file).write_bytes(jsonl)
                m.path = directory / g.mcap
                made[g.name] = m
                break
        else:
            raise RuntimeError(f"goldens: {g.name}: no good recording in {attempts} attempts") from last_error
        truth = true_grades(g)
        wrong = {r: (m.final.get(r), t) for r, t in truth.items() if t is not None and m.final.get(r) != t}
        size = (directory / g.mcap).stat().st_size
        print(f"goldens: {g.mcap}: {m.recorded} messages, {size / 1e3:.0f} kB; {len(m.health)} verdicts "
              f"(health.jsonl sha256 {_sha(jsonl)}); final grades "
              + ("= true grades" if not wrong else f"WRONG (got, true): {wrong}"), file=log)
    (directory / "README.md").write_text(_readme(made, rate))
    return made


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hydromon.tools.goldens", description=__doc__.splitlines()[0])
    parser.add_argument("--update", nargs="*", metavar="NAME", default=None,
                        help="regenerate the named golden recordings (none named: every one), their "
                             ".health.jsonl and the README")
    parser.add_argument("--dir", default=str(RECORDINGS_DIR), help=f"where the goldens live (default {RECORDINGS_DIR})")
    parser.add_argument("--rate", type=float, default=20.0,
                        help="simulation speed while recording, relative to real time (default 20)")
    args = parser.parse_args(argv)
    if args.update is not None:
        write_goldens(args.dir, rate=args.rate, names=args.update or None)
        return 0
    bad = 0
    for g in GOLDENS:
        problems = check_golden(g, args.dir)
        bad += bool(problems)
        print(f"{g.name}: " + ("ok" if not problems else "; ".join(problems)))
    if bad:
        print("run `python -m hydromon.tools.goldens --update` to regenerate them", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
