"""MonitorCore's batch path (regular samples taken together, ``MonitorCore._regular``) against
its per-message path, on streams with every irregularity: the health messages (bytes and
order), the latest health and the counters must be the same whatever the batching."""

from __future__ import annotations

import numpy as np
import orjson
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers import BAD_SAMPLES, working_point_sample
from hydromon.contract import SAMPLE_LIMITS, SEQ_MAX, RigConfig
from hydromon.engine.core import MonitorCore
from hydromon.engine.samples import sim_samples
from hydromon.engine.validate import VALUE_LIMITS, Rejected, decode_json, parse_sample

RIGS = ("ra", "rb", "rc")
CONFIGS = [orjson.dumps(RigConfig().model_dump()), orjson.dumps(RigConfig(p_s=13e6).model_dump())]
ACTIONS = ("next",) * 12 + ("dup", "back", "gap", "restart", "bad", "ints", "config", "health", "badkey")


def stream(draws: list[tuple[int, int, int]]) -> list[tuple[str, bytes]]:
    """Messages from (rig, action, detail) draws: mostly the next sample of a rig."""
    seq = dict.fromkeys(RIGS, -1)
    out = []
    for r, a, d in draws:
        rig, action = RIGS[r], ACTIONS[a]
        key = f"hydro/rig/{rig}/sample"
        if action in ("next", "ints"):
            seq[rig] += 1
            out.append((key, working_point_sample(seq[rig], ints=action == "ints")))
        elif action == "dup" and seq[rig] >= 0:
            out.append((key, working_point_sample(seq[rig])))
        elif action == "back" and seq[rig] >= 2:
            out.append((key, working_point_sample(seq[rig] - 2)))
        elif action == "gap":
            seq[rig] += 2 + d % 5
            out.append((key, working_point_sample(seq[rig])))
        elif action == "restart":
            seq[rig] = 0
            out.append((key, working_point_sample(0)))
        elif action == "bad":
            out.append((key, BAD_SAMPLES[d % len(BAD_SAMPLES)][1]))
        elif action == "config":
            out.append((f"hydro/rig/{rig}/config", CONFIGS[d % 2]))
        elif action == "health":
            out.append((f"hydro/rig/{rig}/health", b"{}"))
        elif action == "badkey":
            out.append((f"hydro/rig/{rig}/sample/x", working_point_sample(0)))
    return out


def reference(msgs):
    """The per-message path alone (how every message was taken before the batch path)."""
    core = MonitorCore("hydro", eval_every=3)
    out: list = []
    for i, (key, payload) in enumerate(msgs):
        core._cur = i
        core._one(key, payload, out)
    core._flush(out)
    return core, [(key, payload) for _, key, payload in out]  # in the order they came out


def per_rig(out):
    got: dict = {}
    for key, payload in out:
        got.setdefault(key, []).append(payload)
    return got


@settings(max_examples=150, deadline=None)
@given(draws=st.lists(st.tuples(st.integers(0, len(RIGS) - 1), st.integers(0, len(ACTIONS) - 1),
                                st.integers(0, 100)), min_size=40, max_size=200),
       cuts=st.lists(st.integers(1, 60), min_size=1, max_size=8))
def test_any_batching_gives_each_rig_the_per_message_result(draws, cuts):
    msgs = stream(draws)
    ref_core, ref = reference(msgs)
    core = MonitorCore("hydro", eval_every=3)
    out, i, k = [], 0, 0
    while i < len(msgs):
        n = cuts[k % len(cuts)]
        out += core.process(msgs[i:i + n])
        i, k = i + n, k + 1
    assert out == ref  # same messages, same bytes, same order
    assert core.counters.as_dict() == ref_core.counters.as_dict()
    assert core.latest == ref_core.latest


def test_a_steady_stream_takes_the_batch_path():
    # the point of the batch path: after each rig's first sample, nothing goes one by one
    msgs = [(f"hydro/rig/{r}/sample", working_point_sample(s)) for s in range(40) for r in RIGS]
    core = MonitorCore("hydro", eval_every=3)
    first = core.process(msgs[:3])
    calls = []
    one = core._one
    core._one = lambda *a: (calls.append(a[0]), one(*a))
    out = core.process(msgs[3:])
    assert calls == [] and core.counters.accepted == 120
    assert first + out == reference(msgs)[1]


def _beyond_limits_only(payload: bytes) -> bool:
    # the sim's shape (numbers: floats or ints), values beyond SAMPLE_LIMITS: sim_samples leaves
    # those to its caller
    try:
        d = orjson.loads(payload)
    except orjson.JSONDecodeError:
        return False
    return isinstance(d, dict) and len(d) == 7 and type(d.get("seq")) is int and 0 <= d["seq"] <= SEQ_MAX \
        and all(type(d.get(k)) in (float, int) for k in SAMPLE_LIMITS) and type(d.get("t")) in (float, int) \
        and any(abs(d[k]) > lim for k, lim in SAMPLE_LIMITS.items())


def test_sim_samples_takes_exactly_the_sims_shape():
    good = working_point_sample(3)
    assert sim_samples([good]) == [tuple(orjson.loads(good).values())]
    beyond = [p for _, p in BAD_SAMPLES if _beyond_limits_only(p)]
    assert len(beyond) >= 3 and None not in sim_samples(beyond)  # the limits are MonitorCore's check
    others = [p for _, p in BAD_SAMPLES if not _beyond_limits_only(p)] + [
        good.replace(b'"seq":3', b'"seq":%d' % (SEQ_MAX + 1)), good.replace(b'"seq":3', b'"seq":' + b"9" * 30),
        good.replace(b'"seq":3', b'"seq":3.0'), good.replace(b'"t":0.03', b'"t":' + b"9" * 400),
        good.replace(b'"t":0.03', b'"t":true'), good + b" x", good.replace(b"}", b',"extra":1}')]
    assert sim_samples(others) == [None] * len(others)
    assert sim_samples([good] + others)[1:] == [None] * len(others)  # one bad one spoils none


def test_what_sim_samples_takes_the_per_message_path_takes_with_the_same_values():
    # integers for floats (valid JSON numbers) are taken on both paths, as floats
    for p in [working_point_sample(3), working_point_sample(250, ints=True)] + [p for _, p in BAD_SAMPLES]:
        fast = sim_samples([p])[0]
        if fast is None:
            continue
        try:
            slow = parse_sample(decode_json(p))
        except Rejected as exc:  # only what MonitorCore checks on the batch's array
            assert exc.reason == "bad-value" and (np.abs(fast[2:]) > VALUE_LIMITS).any(), p
            continue
        assert fast == slow and list(map(type, fast)) == list(map(type, slow)), p


def test_a_config_change_inside_a_batch_applies_from_its_place():
    # samples of ra, ra's constants change, more samples of ra: one batch, and ra's samples
    # after the change must not be taken with those before it
    before = [(f"hydro/rig/{r}/sample", working_point_sample(s)) for s in range(8) for r in RIGS]
    after = [(f"hydro/rig/{r}/sample", working_point_sample(s)) for s in range(8, 20) for r in RIGS]
    msgs = before + [("hydro/rig/ra/config", CONFIGS[1])] + after
    core = MonitorCore("hydro", eval_every=3)
    out = core.process(msgs[:3]) + core.process(msgs[3:])
    ref_core, ref = reference(msgs)
    assert ref_core.counters.config_changes == core.counters.config_changes == 1
    assert out == ref
