"""``hydromon watch``: the board (pure) and the command against a running monitor over loopback."""

from __future__ import annotations

import io
import os
import subprocess
import sys
import threading

import orjson
import pytest

from helpers import wait_for
from hydromon.bus.monitor import run_monitor
from hydromon.bus.session import listening_session
from hydromon.bus.sim import run_sim
from hydromon.engine.board import Board
from hydromon.engine.core import MonitorCore
from hydromon.report.board import BOARD_HEAD, board_counts, board_rows, render_board_plain
from hydromon.store.fleetfile import default_fleet

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _health(level, status="ok", grades=None, seq=10):
    names = ("health", "sub-health", "average", "deterioration", "fault")
    grade = "unknown" if level is None else names[level]
    return orjson.dumps({"seq": seq, "t": seq / 100, "grade": grade, "level": level, "confidence": 0.5,
                         "params": {"K_sv": 2e-4, "f_c": 10.0}, "param_grades": grades or {}, "status": status,
                         "std_errors": {}})


def test_board_orders_rigs_for_attention_and_names_why():
    b = Board()
    b.update("hydro/rig/a/health", _health(1, grades={"K_sv": "sub-health", "f_c": "health"}), 0.0)
    b.update("hydro/rig/b/health", _health(4, grades={"K_sv": "fault", "C_ip": "fault", "f_c": "health"}), 0.0)
    b.update("hydro/rig/c/health", _health(None, status="converging"), 0.0)
    b.update("hydro/rig/d/health", _health(0, status="bad-input", grades={"K_sv": "health"}), 0.0)
    b.update("hydro/rig/e/health", _health(4, status="stale", grades={"K_sv": "fault"}), 0.0)
    b.update("hydro/rig/f/health", _health(0, grades={"K_sv": "health"}), 3.0)
    rows, more = board_rows(b, now=5.0)
    assert more == 0
    col = {name: i for i, name in enumerate(BOARD_HEAD)}
    # bad input first whatever its grade, then worst level first (stale after a live one of
    # the same level), unknown last
    assert [r[0] for r in rows] == ["d", "b", "e", "a", "f", "c"]
    # in words, with the size of the change: the parameters at the rig's grade (C_ip has no value
    # in this payload), not f_c
    assert rows[1][col["why"]] == "valve gain -20 % of its baseline (-5e-05 m/V)"
    assert rows[3][col["why"]] == "valve gain -20 % of its baseline (-5e-05 m/V)"
    assert rows[4][col["why"]] == "-" and rows[5][col["why"]] == "-"  # health / unknown: nothing to blame
    assert rows[4][col["age [s]"]] == "2.0" and rows[1][col["age [s]"]] == "5.0"
    top, more = board_rows(b, now=5.0, top=2)
    assert [r[0] for r in top] == ["d", "b"] and more == 4
    assert "... and 4 more rig(s)" in render_board_plain(b, 5.0, top=2)
    assert board_counts(b) == "6 rig(s): 2 fault, 1 sub-health, 2 health, 1 unknown; 1 with bad input"


def test_board_keeps_the_latest_and_counts_what_it_cannot_show():
    b = Board()
    assert b.update("hydro/rig/a/health", _health(2, seq=10), 1.0)
    assert b.update("hydro/rig/a/health", _health(3, seq=20), 2.0)
    assert b.latest["a"]["level"] == 3 and b.arrived["a"] == 2.0
    # not a Health: counted, and the rig keeps its last valid verdict
    assert not b.update("hydro/rig/a/health", b'{"seq": 30, "grade": "great"}', 3.0)
    assert not b.update("hydro/rig/a/health", b"not json", 3.0)
    assert not b.update("hydro/rig/a/sample", _health(0), 3.0)
    assert not b.update("other/rig/a/health", _health(0), 3.0)
    assert b.latest["a"]["level"] == 3 and (b.invalid, b.foreign) == (2, 2)
    assert "2 invalid payload(s) ignored" in board_counts(b)


def _watch(*args, timeout=90):
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-m", "hydromon.cli", "watch", *args], check=False, capture_output=True,
                          text=True, timeout=timeout, env=env)


@pytest.mark.network
@pytest.mark.timeout(180)
def test_watch_once_asks_the_running_monitor():
    spec = default_fleet()
    core = MonitorCore()
    stop = threading.Event()
    with listening_session() as (session, ep):
        mon = threading.Thread(target=run_monitor, args=(session,), daemon=True,
                               kwargs={"stop_event": stop, "core": core, "stale_after_s": None})
        mon.start()
        try:
            wait_for(lambda: any(r.ok is not None for r in session.liveliness().get("hydro/monitor/monitor",
                                                                                     timeout=1.0)), 60, "monitor")
            run_sim(session, spec, rate=0, duration=5.0)
            wait_for(lambda: len(core.latest) == 5 and core.counters.accepted == 5 * 500, 60, "every verdict")
            out = _watch("--once", "--json", "--connect", ep)
            part = _watch("--once", "--rigs", "table4-g1", "--connect", ep)
        finally:
            stop.set()
            mon.join(30)
    assert out.returncode == 0, out.stderr
    doc = orjson.loads(out.stdout)
    assert sorted(doc["rigs"]) == sorted(spec.ids)
    for rig, h in doc["rigs"].items():  # what the monitor holds, byte for byte as parsed
        assert h == orjson.loads(core.latest[rig])
    assert sum(doc["counts"].values()) == 5 and doc["invalid"] == 0
    assert part.returncode == 0, part.stderr
    assert "1 rig(s)" in part.stdout and "table4-g1" in part.stdout and "table4-g2" not in part.stdout


def _event(seq, to="fault", reason="valve gain -44 % of its baseline"):
    return orjson.dumps({"seq": seq, "t": seq / 100, "kind": "grade", "from": "health", "to": to, "reason": reason})


def test_board_keeps_the_latest_events_newest_first():
    b = Board()
    for i in range(12):
        assert b.event(f"hydro/rig/r{i}/event", _event(i), float(i))
    assert not b.event("hydro/rig/a/event", b'{"seq": 1, "kind": "mood"}', 12.0)
    assert not b.event("hydro/rig/a/health", _event(1), 12.0)
    assert (b.invalid, b.foreign) == (1, 1)
    text = render_board_plain(b, 12.0)
    lines = text.splitlines()[text.splitlines().index("latest events:") + 1:]
    assert len(lines) == 8 and lines[0].split() == ["1.0", "s", "ago", "r11", "grade", "health", "->", "fault:",
                                                   "valve", "gain", "-44", "%", "of", "its", "baseline"]
    assert "r3 " not in text and lines[-1].split()[3] == "r4"


@pytest.mark.network
@pytest.mark.timeout(120)
def test_watch_shows_the_events_it_hears():
    stop = threading.Event()
    with listening_session() as (session, ep):
        def publish():  # until watch has heard one: it subscribes a moment after it starts
            seq = 0
            while not stop.wait(0.2):
                seq += 1
                session.put("hydro/rig/press-7/event", _event(seq, reason="internal leakage past the fault threshold"))

        t = threading.Thread(target=publish, daemon=True)
        t.start()
        try:
            r = _watch("--plain", "--duration", "4", "--wait", "0.5", "--connect", ep)
        finally:
            stop.set()
            t.join(5)
    assert r.returncode == 0, r.stderr
    last = r.stdout.rsplit("latest events:", 1)[-1].splitlines()[1]
    assert "press-7  grade health -> fault: internal leakage past the fault threshold" in last, r.stdout


@pytest.mark.network
@pytest.mark.timeout(120)
def test_watch_once_with_no_monitor_says_so():
    with listening_session() as (_, ep):
        r = _watch("--once", "--wait", "0.5", "--connect", ep)
    assert r.returncode == 1
    assert "no monitor answered" in r.stderr and r.stdout == ""


@pytest.mark.parametrize("args, message", [
    (["--json"], "--json needs --once"),
    (["--once", "--duration", "3"], "--duration has no effect with --once"),
    (["--wait", "0"], "--wait"),
    (["--top", "-1"], "--top"),
    (["--rigs", "a/b"], "--rigs"),
])
def test_watch_refuses_bad_options_before_the_bus(args, message):
    r = _watch(*args, timeout=60)
    assert r.returncode == 2 and message in r.stderr, r.stderr


def test_rich_board_fits_the_terminal_by_dropping_the_least_needed_columns():
    from rich.console import Console

    from hydromon.report.board import render_board_rich

    b = Board()
    b.update("hydro/rig/table4-g3/health", _health(4, grades={"C_ip": "fault", "C_ep": "fault", "K_sv": "fault"}), 0.0)
    b.update("hydro/rig/table4-g2/health", _health(0, grades={"K_sv": "health"}), 0.0)
    # the why column (words, wrapped) takes its share: at 80 columns the least needed numbers go
    for width, gone in ((200, ()), (100, ("t [s]",)), (80, ("t [s]", "C_ip", "B_fv", "f_c"))):
        console = Console(width=width, record=True, file=io.StringIO())
        console.print(render_board_rich(b, 1.0, None, "hydromon watch", width))
        text = console.export_text()
        assert "…" not in text, text  # no number or name cut short
        assert "valve gain -20 % of its baseline" in " ".join(text.split()) and "table4-g3" in text
        header = next(line for line in text.splitlines() if "grade" in line and "rig" in line)
        for name in BOARD_HEAD:
            assert (name in header) == (name not in gone), (width, name, header)


def test_a_verdicts_age_is_since_it_was_published_and_unknown_from_a_query_answer():
    """watch --once: a monitor's answer to the query is its last verdict, of unknown age ('-');
    a verdict published while watch listens is as old as its arrival, and the same verdict re-sent
    (a silent rig's, marked stale) keeps that age, as the live view shows it."""
    from hydromon.cli.commands.watch import Ages
    from hydromon.report.board import AGE_UNKNOWN

    b = Board()
    ages = Ages(b)
    ages.update("hydro/rig/a/health", _health(1, seq=10), 0.0, published=False)
    ages.update("hydro/rig/s/health", _health(1, status="stale", seq=50), 0.0, published=False)
    ages.update("hydro/rig/a/health", _health(1, seq=20), 1.0)  # published while listening
    ages.update("hydro/rig/s/health", _health(1, status="stale", seq=50), 1.0)  # the stale re-send
    ages.update("hydro/rig/s/health", _health(1, status="stale", seq=50), 3.0)  # and again, 2 s later
    rows, _ = board_rows(b, 3.5, since=ages.since)
    age = {r[0]: r[BOARD_HEAD.index("age [s]")] for r in rows}
    assert age == {"a": "2.5", "s": "2.5"}
    ages.update("hydro/rig/n/health", _health(2, seq=5), 3.5, published=False)  # answered, never published
    text = render_board_plain(b, 4.0, since=ages.since)
    assert {r[0]: r[BOARD_HEAD.index("age [s]")] for r in board_rows(b, 4.0, since=ages.since)[0]}["n"] == "-"
    assert AGE_UNKNOWN in text
