"""The live monitor says ``bad-input`` for a rig whose readings stopped changing
(``hydromon.engine.frozen_watch``): a stalled acquisition re-sending its last reading, its seq
still counting, is not silent, and its estimates learn nothing from it."""

from __future__ import annotations

import orjson
import pytest

from hydromon.engine.core import MonitorCore
from hydromon.engine.frozen_watch import FROZEN_S
from helpers import core_messages, health_however_batched, run_core
from plant_sim.degradation import degrade
from plant_sim.noise import noise_model
from plant_sim.profiles import parse_profile
from plant_sim.simulate import simulate

NS = "hydro"


@pytest.fixture(scope="module", params=["realistic", "none"])
def run(request):
    return simulate(parse_profile("steps"), 16.0, params=degrade(0.3), noise=noise_model(request.param), seed=2)


def _frozen(run, spans):
    """The record with each (start, end) sample span repeating the sample before it."""
    s = run.samples.copy()
    for a, b in spans:
        s[a:b] = s[a - 1]
    return s


def _messages(run, samples, frame=None, rig="a"):
    return core_messages(run, samples, frame, rig, NS)


def _run(msgs, batch=None):
    return run_core(msgs, batch, NS)


def test_a_rig_whose_readings_stop_changing_says_bad_input_from_two_seconds_on_and_is_warned_once(run):
    need = int(FROZEN_S * 100)
    health, warnings = _run(_messages(run, _frozen(run, [(600, 1000), (1200, 1500)])), batch=50)
    status = {h["seq"]: h["status"] for h in health}
    frozen = [s for s in status if 600 + need - 1 <= s < 1000 or 1200 + need - 1 <= s < 1500]
    assert len(frozen) > 20 and {status[s] for s in frozen} == {"bad-input"}
    # nothing before: the first 2 s of a freeze may be a rig at rest
    assert "bad-input" not in {status[s] for s in status if s < 600 + need - 1}
    if run.noise.name == "realistic":  # nor between them (the estimates a freeze spoils may say so themselves)
        assert {status[s] for s in status if 1000 <= s < 1200} == {"ok"}
    told = [w for w in warnings if "repeated one reading" in w[1]]
    assert len(told) == 2 and told[0][0] == "a", warnings  # once a freeze


def test_a_record_that_never_freezes_is_never_flagged(run):
    health, warnings = _run(_messages(run, run.samples), batch=50)
    assert "bad-input" not in {h["status"] for h in health} and not any("repeated" in w[1] for w in warnings)


def test_the_health_does_not_depend_on_how_the_messages_were_batched_or_framed(run):
    s = _frozen(run, [(650, 990)])
    assert any(h["status"] == "bad-input" for h in health_however_batched(run, s, NS))


def test_a_forgotten_rig_s_row_carries_no_reading_into_the_next_rig(run):
    core = MonitorCore(NS)
    s = run.samples
    core.process(_messages(run, s[:300], rig="old"))
    row = core.rigs["old"].row
    core.forget(["old"])
    # the next rig in its row starts with the old rig's last reading, repeated: its first sample
    # repeats nothing (the old rig's is not its own), the next 49 repeat it
    frozen = s.copy()
    frozen[:50] = s[299]
    core.process(_messages(run, frozen[:50], rig="new"))
    assert core.rigs["new"].row == row and core._same[row] == 49


def test_each_freeze_is_warned_of_in_one_batch_as_in_many(run):
    s = _frozen(run, [(300, 600), (700, 1000)])
    msgs = _messages(run, s)
    for batch in (None, 100):
        _, warnings = _run(msgs, batch)
        assert sum("repeated one reading" in w[1] for w in warnings) == 2, (batch, warnings)


def test_interleaved_rigs_are_watched_each_on_its_own(run):
    a, b = _messages(run, _frozen(run, [(300, 700)]), rig="a"), _messages(run, run.samples, rig="b")
    mixed = [m for pair in zip(a, b) for m in pair]
    health, warnings = _run(mixed, batch=37)
    bad = {(h["seq"], r) for (h, r) in [(orjson.loads(p), k.split("/")[2]) for k, p in
                                        MonitorCore(NS).process(mixed)] if h["status"] == "bad-input"}
    assert bad and {r for _, r in bad} == {"a"} and [w[0] for w in warnings if "repeated" in w[1]] == ["a"]
