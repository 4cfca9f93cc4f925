"""Grade and status changes are announced once they hold, never while an estimate wavers."""

import orjson
from hypothesis import given, settings
from hypothesis import strategies as st

from hydromon.contract import Event
from hydromon.engine.events import Announcer, event_payload


def test_a_change_is_announced_after_it_holds_and_the_first_verdict_is_the_state():
    a = Announcer(hold=3)
    assert a.observe(0, -1, "converging") is None          # the first verdict: the state
    assert a.observe(0, 0, "ok") is None
    assert a.observe(0, 0, "ok") is None
    assert a.observe(0, 0, "ok") == ((-1, "converging"), (0, "ok"))
    assert a.observe(0, 0, "ok") is None
    assert a.observe(0, 1, "ok") is None and a.observe(0, 0, "ok") is None  # a blip: nothing
    assert a.observe(0, 1, "ok") is None and a.observe(0, 1, "ok") is None
    assert a.observe(0, 1, "ok") == ((0, "ok"), (1, "ok"))
    assert a.observe(0, 1, "stale", now=True) == ((1, "ok"), (1, "stale"))
    a.reset(0)
    assert a.observe(0, 4, "ok") is None  # a new rig in the row: its first verdict


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(-1, 4), st.sampled_from(["ok", "converging", "bad-input"])),
                min_size=1, max_size=60), st.integers(1, 4))
def test_every_announcement_held_for_its_count_and_no_two_in_a_row_are_equal(verdicts, hold):
    a = Announcer(hold=hold)
    announced = [verdicts[0]]
    for i, v in enumerate(verdicts):
        change = a.observe(0, *v)
        if change is not None:
            before, after = change
            assert before == announced[-1] and after == v and before != after
            assert verdicts[i - hold + 1:i + 1] == [v] * hold  # it held
            announced.append(after)


def test_the_event_payload_is_the_contracts():
    p = event_payload(12, 0.12, "grade", "health", "fault", "K_sv at fault", "m1", 3)
    e = Event.model_validate_json(p)
    assert e.from_ == "health" and orjson.loads(p)["from"] == "health" and e.node == "m1"
