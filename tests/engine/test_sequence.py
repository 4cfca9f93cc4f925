"""Sequence numbers one bad message cannot hijack: swapped neighbours put back in order, a lone
seq far ahead dropped, a real jump taken once a run confirms it, nothing real lost."""

import numpy as np
import orjson
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers import by_rig, fleet_messages
from hydromon.contract import Health
from hydromon.engine.core import MonitorCore
from hydromon.engine.sequence import AHEAD, CONFIRM, FAR, GAP, TAKE, sequence_order
from hydromon.store.fleetfile import default_fleet


def test_swapped_neighbours_are_put_back_in_order_with_no_gap():
    seq = [0, 1, 2, 4, 3, 5, 6, 8, 7, 9]
    order, verdicts, dropped = sequence_order(np.array(seq))
    assert [seq[i] for i in order] == list(range(10)) and set(verdicts.tolist()) == {TAKE}
    assert (dropped == -1).all()


def test_a_lone_seq_far_ahead_is_dropped_and_a_confirmed_jump_is_taken_whole():
    seq = list(range(20)) + [10**15] + list(range(20, 40))
    order, verdicts, dropped = sequence_order(np.array(seq))
    assert [seq[i] for i in order] == list(range(40)) and set(verdicts.tolist()) == {TAKE}
    assert dropped[20] == AHEAD
    jump = list(range(20)) + list(range(20 + FAR + 500, 20 + FAR + 500 + CONFIRM + 5))
    order, verdicts, _ = sequence_order(np.array(jump))
    assert [jump[i] for i in order] == jump and verdicts[20] == GAP and (verdicts[21:] == TAKE).all()


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 60), max_size=80), st.integers(0, 10**6))
def test_every_sample_is_taken_once_or_dropped_and_taken_seqs_only_grow_between_restarts(raw, offset):
    seq = np.array(raw, dtype=np.int64) + offset * (np.array(raw) > 30)
    order, verdicts, dropped = sequence_order(seq)
    assert sorted(order.tolist() + np.flatnonzero(dropped >= 0).tolist()) == list(range(len(seq)))
    taken = seq[order]
    for k in range(1, len(taken)):
        assert taken[k] > taken[k - 1] or verdicts[k] == 4  # RESTART


def _messages_with(mutate):
    return mutate(fleet_messages(default_fleet(noise="realistic"), 12.0))


def test_one_adjacent_swap_in_every_ten_samples_still_grades_every_rig_right():
    def swap(msgs):
        samples = [i for i, (k, _) in enumerate(msgs) if k == "hydro/rig/table4-g3/sample"]
        for a in samples[5::10]:
            b = samples[samples.index(a) + 1]
            msgs[a], msgs[b] = msgs[b], msgs[a]
        return msgs

    core = MonitorCore()
    health = by_rig(core.process(_messages_with(swap)))
    last = Health.model_validate_json(health["table4-g3"][-1])
    assert (last.grade, last.status) == ("fault", "ok")
    assert core.counters.gaps == 0 and core.counters.dropped_seq == 0 and core.counters.accepted == 5 * 1200


def test_one_forged_seq_far_ahead_drops_nothing_real_and_resets_nothing():
    def forge(msgs):
        i = [j for j, (k, _) in enumerate(msgs) if k == "hydro/rig/table4-g1/sample"][400]
        d = orjson.loads(msgs[i][1])
        return msgs[:i] + [(msgs[i][0], orjson.dumps(dict(d, seq=10**15)))] + msgs[i:]

    clean, forged = MonitorCore(), MonitorCore()
    a, b = clean.process(_messages_with(lambda m: m)), forged.process(_messages_with(forge))
    assert a == b  # the same verdicts, byte for byte
    c = forged.counters
    assert (c.ahead, c.gaps, c.missing, c.restarts, c.accepted) == (1, 0, 0, 0, 5 * 1200)
