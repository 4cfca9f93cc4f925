"""The dashboard's state without a bus or a browser: rows worst first with why and since when, the
flags of rigs whose verdict is not current, history decimation, and the event log across a
restart."""

from __future__ import annotations

import orjson

from hydromon.contract import Health
from hydromon.dashboard.eventlog import EventLog
from hydromon.dashboard.fleet import SILENT, Fleet, row_order
from hydromon.engine.board import NO_MONITOR
from hydromon.dashboard.history import RigHistory
from monitor.ranges import Ranges


def health(grade="health", level=0, status="ok", node="mon1", seq=9, k_sv=2.5e-4, **kw) -> bytes:
    params = {"K_sv": k_sv, "f_c": 10.0}
    h = Health(seq=seq, t=seq / 100, grade=grade, level=level, confidence=0.8, params=params,
               param_grades={"K_sv": grade, "f_c": "health"}, status=status, std_errors={"K_sv": 1e-6},
               node=node, **kw)
    return h.model_dump_json().encode()


def test_rows_worst_first_why_in_words_and_since_when():
    f = Fleet()
    f.put_monitor("mon1", True, 0.0)
    f.put_health("a", health(), 1.0)
    f.put_health("b", health("fault", 4, k_sv=1e-4), 1.0)
    f.put_health("c", health("average", 2, status="bad-input"), 1.0)
    f.put_health("d", health("fault", 4, status="stale"), 1.0)
    f.put_health("e", b"{not json", 1.0)
    t = f.tick(1.1)
    order = [r["rig"] for r in sorted(t.rows, key=row_order)]
    assert order == ["c", "b", "d", "a"]
    assert t.counts["grades"] == {"fault": 2, "average": 1, "health": 1} and t.counts["invalid"] == 1
    rows = {r["rig"]: r for r in t.rows}
    assert rows["b"]["why"] == ["valve gain 0.0001 m/V"]  # no ranges: the value and its unit
    f.set_ranges("b", Ranges.default())
    t = f.tick(1.2)
    assert [r["rig"] for r in t.rows] == ["b"]  # only what changed is pushed
    assert t.rows[0]["why"][0].startswith("valve gain -") and "baseline" in t.rows[0]["why"][0]
    # since: when the grade last changed, not when the latest verdict came
    f.put_health("b", health("fault", 4, k_sv=1.1e-4), 5.0)
    f.put_health("a", health("sub-health", 1), 5.0)
    rows = {r["rig"]: r for r in f.tick(5.1).rows}
    assert rows["b"]["since"] == 1.0 and rows["b"]["arrived"] == 5.0
    assert rows["a"]["since"] == 5.0


def test_flags_no_monitor_and_silent():
    f = Fleet()
    f.put_monitor("mon1", True, 0.0)
    f.put_monitor("mon2", True, 0.0)
    f.put_health("a", health(node="mon1"), 1.0)
    f.put_health("b", health(node="mon2"), 1.0)
    f.put_health("c", health(node=None), 1.0)
    assert all(r["flag"] is None for r in f.tick(1.1).rows)
    f.put_monitor("mon1", False, 1.2)
    t = f.tick(1.3)
    assert {r["rig"]: r["flag"] for r in t.rows} == {"a": NO_MONITOR}
    assert [(e["kind"], e["node"], e["to"]) for e in t.events] == [("monitor", "mon1", "gone")]
    assert "1 rig(s) without a monitor" in t.events[0]["reason"]
    # a verdict that names no monitor: flagged once no monitor at all is up
    f.put_monitor("mon2", False, 1.4)
    f.tick(1.5)
    flags = {r["rig"]: r["flag"] for r in f.fleet_snapshot(1.5)["rows"]}
    assert flags == {"a": NO_MONITOR, "b": NO_MONITOR, "c": NO_MONITOR}
    f.put_monitor("mon2", True, 2.0)
    f.put_health("b", health(node="mon2"), 2.0)
    rows = {r["rig"]: r["flag"] for r in f.tick(2.1).rows}
    assert rows["b"] is None and rows["c"] is None
    assert {r["rig"]: r["flag"] for r in f.tick(4.5).rows} == {"b": SILENT, "c": SILENT}
    # rows flagged go last
    f.put_health("d", health(node="mon2"), 4.5)
    f.tick(4.5)
    assert [r["rig"] for r in f.fleet_snapshot(4.5)["rows"]] == ["d", "a", "b", "c"]


def test_a_verdict_of_an_earlier_start_of_the_monitor_is_not_taken():
    f = Fleet()
    f.put_monitor("mon1", True, 0.0)
    f.put_health("a", health("fault", 4, epoch=7), 1.0)
    f.tick(1.0)
    f.put_health("a", health("health", 0, epoch=6), 1.1)  # late, from before the monitor's restart
    assert f.tick(1.2).rows == [] and f.not_shown == 1
    f.put_health("a", health("health", 0, epoch=8), 1.3)
    assert [r["grade"] for r in f.tick(1.4).rows] == ["health"]
    # as watch: not a verdict from a monitor that is not up, nor another's while the rig's own is up
    f.put_health("a", health("fault", 4, node="ghost"), 1.5)
    f.put_monitor("mon2", True, 1.5)
    f.tick(1.6)
    f.put_health("a", health("fault", 4, node="mon2"), 1.7)
    assert f.tick(1.8).rows == [] and f.not_shown == 3
    f.put_monitor("mon1", False, 1.9)
    f.put_health("a", health("fault", 4, node="mon2"), 1.9)  # its own gone, another takes the rig over
    assert [(r["grade"], r["node"], r["flag"]) for r in f.tick(2.0).rows] == [("fault", "mon2", None)]


def test_history_keeps_a_point_a_second_and_one_every_six():
    hist = RigHistory()
    h = orjson.loads(health())
    for i in range(100):  # 10 s at 10 per second
        hist.take(i * 0.1, h)
    pts = hist.points()
    assert pts["wall"] == [float(i) for i in range(10)]
    assert pts["value"]["K_sv"][0] == 2.5e-4 or abs(pts["value"]["K_sv"][0] - 2.5e-4) < 1e-10
    assert pts["value"]["m"][0] is None  # not in the verdict
    assert hist.points(since=7.0)["wall"] == [8.0, 9.0]
    for i in range(100, 4000):  # past the fine ring's 5 minutes: the coarse one reaches back
        hist.take(i * 0.1, h)
    pts = hist.points()
    assert pts["wall"][0] == 0.0 and pts["wall"][1] == 6.0
    assert pts["wall"] == sorted(pts["wall"]) and pts["wall"][-1] == 399.0


def test_event_log_survives_a_restart_with_its_acknowledgements(tmp_path):
    path = tmp_path / "state" / "events.jsonl"
    log = EventLog(path)
    a = log.add({"wall": 1.0, "rig": "r1", "kind": "grade", "from": "health", "to": "fault", "reason": "x"})
    log.add({"wall": 2.0, "rig": "r2", "kind": "status", "from": "ok", "to": "stale", "reason": ""})
    log.ack(a["id"], "valve replaced", "anna", 3.0)
    log.close()
    with open(path, "ab") as f:
        f.write(b'{"id": 3, "wall": 4.0, "rig": "r3"')  # a line cut short by a crash
    log = EventLog(path)
    assert log.skipped == 1
    got = log.recent()
    assert [e["rig"] for e in got] == ["r2", "r1"]
    assert got[1]["ack"] == {"wall": 3.0, "comment": "valve replaced", "by": "anna"}
    assert log.add({"rig": "r4"})["id"] == 3
    log.close()


def test_a_rig_page_opened_before_the_rig_s_first_verdict_or_ranges_is_sent_them_whole():
    from hydromon.dashboard.app import Hub

    fleet = Fleet(EventLog(None))
    hub = Hub(fleet, clock=lambda: 1.0)
    first = hub.snapshot("rig", "r1")
    assert first["health"] is None and first["ranges"] is None  # opened before anything came
    fleet.put_health("r1", health(), 1.0)
    msg = hub.messages(fleet.tick(1.1, {"r1"}), "rig", "r1")
    assert msg["type"] == "rig" and msg["health"]["param_grades"] == {"K_sv": "health", "f_c": "health"}
    msg = hub.messages(fleet.tick(1.2, {"r1"}), "rig", "r1")
    assert msg["type"] == "rig-delta"  # after that, what changed
    fleet.set_ranges("r1", Ranges.default())  # the monitor answered the ranges query
    msg = hub.messages(fleet.tick(1.3, {"r1"}), "rig", "r1")
    assert msg["type"] == "rig" and msg["ranges"] is not None and msg["ranges_from"] == "monitor"
    assert hub.messages(fleet.tick(1.4, {"r1"}), "rig", "r1")["type"] == "rig-delta"


def test_an_acknowledgement_needs_a_name_in_text_and_is_never_replaced():
    import pytest

    from hydromon.dashboard.eventlog import AlreadyAcknowledged

    log = EventLog(None)
    ev = log.add({"wall": 1.0, "rig": "r1", "kind": "grade", "from": "health", "to": "fault", "reason": "x"})
    for comment, by in (("", ""), ("looked", "  "), (None, "anna"), ("ok", ["x"]), ("ok", 7)):
        with pytest.raises(ValueError, match="^(comment|by): "):
            log.ack(ev["id"], comment, by, 2.0)
    assert log.recent()[0].get("ack") is None
    log.ack(ev["id"], "valve replaced", "anna", 3.0)
    with pytest.raises(AlreadyAcknowledged, match="already acknowledged by anna at 1970-01-01 00:00:03 UTC"):
        log.ack(ev["id"], "mine now", "bob", 4.0)
    assert log.recent()[0]["ack"] == {"wall": 3.0, "comment": "valve replaced", "by": "anna"}


def test_since_is_taken_from_the_event_log_across_a_restart(tmp_path):
    path = tmp_path / "events.jsonl"
    log = EventLog(path)
    log.add({"wall": 10.0, "rig": "r1", "kind": "grade", "from": "average", "to": "fault", "reason": "x"})
    log.add({"wall": 12.0, "rig": "r2", "kind": "grade", "from": "fault", "to": "average", "reason": "y"})
    log.close()
    fleet = Fleet(EventLog(path))  # the dashboard started again on its log
    fleet.put_health("r1", health(grade="fault", level=4), 30.0)
    fleet.put_health("r2", health(grade="health", level=0), 30.0)  # its newest change led elsewhere
    rows = {r["rig"]: r for r in fleet.tick(30.5).rows}
    assert rows["r1"]["since"] == 10.0 and rows["r2"]["since"] == 30.0
