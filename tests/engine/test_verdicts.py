"""The live core grades a rig only on ranges made for it: a rig of another size is reported
uncalibrated until it has its own; each verdict names its ranges and its monitor; grade and
status changes are announced as events."""

import orjson
import pytest

from helpers import by_rig, fleet_messages
from hydromon.contract import Event, Health, RigConfig
from hydromon.engine.core import MonitorCore
from hydromon.engine.ranges_book import RangesBook
from hydromon.store.fleetfile import FleetSpec, RigSpec
from monitor.relative import relative_ranges

OTHER = {"A1": 0.012, "A2": 0.006, "V10": 0.15, "V20": 0.12, "p_s": 16e6, "F_L": 6000.0}
BASE = {"m": 300.0, "B": 12000.0, "K_sv": 1.4e-4, "f_c": 12.0, "f_v": 50.0}
SPEC = FleetSpec(seed=4, rigs=[RigSpec(id="ref", table4=2, noise="realistic"),
                               RigSpec(id="big", base=BASE, config=OTHER, severity=0.5, noise="realistic")])
MSGS = fleet_messages(SPEC, 8.0)


def _own_ranges():
    rig = SPEC.rigs[1]
    return relative_ranges(rig.healthy().identified(), rig.rig_config(SPEC.config))[0]


def test_a_rig_of_another_size_is_reported_uncalibrated_with_its_parameters():
    warned = []
    core = MonitorCore(on_warning=lambda rig, msg: warned.append((rig, msg)), node="m1", epoch=7)
    out = by_rig(core.process(MSGS))
    big = [Health.model_validate_json(p) for p in out["big"]]
    assert {h.status for h in big[-10:]} == {"uncalibrated"} and {h.grade for h in big} == {"unknown"}
    assert big[-1].ranges is None and big[-1].param_grades == {} and "K_sv" in big[-1].params
    assert (big[-1].node, big[-1].epoch) == ("m1", 7)
    ref = Health.model_validate_json(out["ref"][-1])
    assert (ref.grade, ref.status, ref.ranges) == ("health", "ok", "default")
    assert [m for r, m in warned if r == "big" and m.startswith("not graded")] and not [r for r, _ in warned if r == "ref"]


def test_its_own_ranges_grade_it_from_when_they_arrive():
    book = RangesBook()
    core = MonitorCore(book=book)
    core.process(MSGS[:400])
    book.set("big", _own_ranges(), "big.json (2026-11-27)")
    core.ranges_changed("big")
    big = [Health.model_validate_json(p) for p in by_rig(core.process(MSGS[400:]))["big"]]
    assert big[-1].grade == "average" and big[-1].status == "ok" and big[-1].ranges == "big.json (2026-11-27)"
    ranges, tag = core.ranges_of("big")
    assert ranges.made_for(RigConfig(**{**RigConfig().model_dump(), **OTHER})) is None and tag.startswith("big.json")


def test_grade_and_status_changes_come_as_events_once_they_hold():
    core = MonitorCore(node="m1", epoch=1)
    core.process(MSGS)
    events = [(k, Event.model_validate_json(p)) for k, p in core.take_events()]
    assert core.take_events() == []  # taken once
    ref = [e for k, e in events if k == "hydro/rig/ref/event"]
    # converging -> ok as the estimates converge, and the first grade
    assert ("status", "converging", "ok") in [(e.kind, e.from_, e.to) for e in ref]
    grade = [e for e in ref if e.kind == "grade"]
    assert grade and grade[-1].to == "health" and grade[0].from_ == "unknown" and grade[0].node == "m1"
    big = [e for k, e in events if k == "hydro/rig/big/event"]
    assert not [e for e in big if e.kind == "grade"]  # an uncalibrated rig's grade stays unknown
    # a silent rig's stale verdict is announced at once
    core.stale(["ref"])
    [(key, payload)] = core.take_events()
    e = orjson.loads(payload)
    assert key == "hydro/rig/ref/event" and (e["kind"], e["from"], e["to"]) == ("status", "ok", "stale")


@pytest.mark.parametrize("hold", [1, 3])
def test_events_never_flap_between_two_verdicts_within_the_hold(hold):
    from hydromon.engine.events import Announcer

    a = Announcer(hold)
    a.observe(0, 1, "ok")
    changes = [a.observe(0, lv, "ok") for lv in [2, 1] * 10]
    # held for three evaluations, a level wavering between two bands makes no event; announced at
    # once (hold 1), every waver is one
    assert sum(c is not None for c in changes) == (0 if hold == 3 else 20)
