"""Frames at the monitor core: the same health as samples, byte for byte and at the same samples,
and every kind of malformed frame rejected and counted at the edge."""

from __future__ import annotations

import orjson
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers import assert_clean_but_flagged, by_rig, fleet_messages, health_seqs
from hydromon.contract import FRAME_MAX, SEQ_MAX, Frame, Health
from hydromon.engine.core import MonitorCore
from hydromon.engine.frames import decode_frame, frame_payload
from hydromon.engine.validate import REJECT_REASONS, Rejected, parse_frame
from hydromon.store.fleetfile import default_fleet

NS = "hydro"
SPEC = default_fleet(noise="realistic")
SAMPLES = fleet_messages(SPEC, 6.0)


def run(msgs, chunk=None):
    core = MonitorCore(NS)
    out = []
    for i in range(0, len(msgs), chunk or len(msgs)):
        out += core.process(msgs[i:i + (chunk or len(msgs))])
    return core, out


@pytest.fixture(scope="module")
def by_samples():
    return run(SAMPLES)


@pytest.mark.parametrize("frame,chunk", [(10, None), (7, 40), (1, 333), (200, 3)])
def test_health_is_the_same_byte_for_byte_with_frames(by_samples, frame, chunk):
    _, want = by_samples
    core, got = run(fleet_messages(SPEC, 6.0, frame=frame), chunk)
    assert core.counters.accepted == 600 * 5 and core.counters.rejected_total == 0
    got, want = by_rig(got), by_rig(want)
    assert got == want
    for rig, payloads in got.items():  # after every 10th sample of the rig, staggered as samples are
        assert [Health.model_validate_json(p).seq for p in payloads] == health_seqs(rig, 600)


def test_samples_and_frames_of_one_rig_mixed(by_samples):
    """A rig switching between samples and frames (and rigs of both kinds in one batch)."""
    _, want = by_samples
    framed = [m for m in fleet_messages(SPEC, 6.0, frame=10) if m[0].endswith("/frame")]
    samples = [m for m in SAMPLES if m[0].endswith("/sample")]
    configs = [m for m in SAMPLES if m[0].endswith("/config")]
    g1 = "hydro/rig/table4-g1/"
    mixed = []
    for k, p in samples:  # g1: samples 0-99 one by one, then frames, then samples again
        seq = orjson.loads(p)["seq"]
        if not (k.startswith(g1) and 100 <= seq < 400) and not k.startswith("hydro/rig/table4-g2/"):
            mixed.append((k, p))
    mixed[len(mixed) // 3:len(mixed) // 3] = [(k, p) for k, p in framed if k.startswith(g1)
                                               and 100 <= orjson.loads(p)["seq"] < 400]
    mixed += [(k, p) for k, p in framed if k.startswith("hydro/rig/table4-g2/")]
    # g1's frames come before its samples 400.. in the list; put its samples 400.. after them
    tail = [(k, p) for k, p in mixed if k.startswith(g1 + "sample") and orjson.loads(p)["seq"] >= 400]
    mixed = [m for m in mixed if m not in tail] + tail
    core, got = run(configs + mixed, chunk=500)
    assert core.counters.accepted == 3000 and core.counters.dropped_seq == 0 and core.counters.gaps == 0
    assert by_rig(got) == by_rig(want)


# -- malformed frames -----------------------------------------------------------------------------

N = 10
GOOD = {"seq": 20, "t": [0.2 + 0.01 * i for i in range(N)], "ug": [0.1] * N, "x1": [0.01] * N,
        "x3": [5e6] * N, "x4": [6e6] * N, "x5": [1e-5] * N}


def frame_with(**kw) -> bytes:
    d = {**GOOD, **kw}
    return orjson.dumps({k: v for k, v in d.items() if v is not None})


def _nan(field: str) -> bytes:
    return frame_with(**{field: [0.123456] + GOOD[field][1:]}).replace(b"0.123456", b"NaN")


BAD_FRAMES = [
    ("not-json", b"{not json"),
    ("wrong-type", b"[1, 2]"),
    ("wrong-type", frame_with(x1=0.01)),                       # a number, not an array
    ("wrong-type", frame_with(ug=[0.1] * (N - 1) + ["0.1"])),
    ("wrong-type", frame_with(x3=[True] * N)),
    ("wrong-type", frame_with(seq=20.0)),
    ("missing-field", frame_with(x5=None)),
    ("unknown-field", frame_with(seqs=list(range(20, 30)))),
    ("non-finite", _nan("x1")),
    ("non-finite", _nan("t")),
    ("bad-value", frame_with(ug=[0.1] * (N - 1))),             # wrong length
    ("bad-value", frame_with(t=GOOD["t"] + [0.3])),
    ("bad-value", frame_with(u=[0.1] * (N + 2))),
    ("bad-value", frame_with(t=[], ug=[], x1=[], x3=[], x4=[], x5=[])),
    ("bad-value", frame_with(t=GOOD["t"][:5] + GOOD["t"][4:9])),  # time repeats
    ("bad-value", frame_with(t=GOOD["t"][::-1])),              # time goes back
    ("bad-value", frame_with(x3=[5e6] * (N - 1) + [2e9])),     # beyond SAMPLE_LIMITS
    ("bad-value", frame_with(u=[0.1] * (N - 1) + [2e3])),
    ("bad-value", frame_with(seq=-1)),
    ("bad-value", frame_with(seq=SEQ_MAX - 5)),                # its last sample's seq beyond SEQ_MAX
]


@pytest.mark.parametrize("reason,payload", BAD_FRAMES)
def test_every_kind_of_malformed_frame_is_rejected_with_its_reason(reason, payload):
    with pytest.raises(Rejected) as exc:
        decode_frame(payload)
    assert exc.value.reason == reason


def test_malformed_frames_are_counted_and_the_rigs_other_frames_graded_as_before():
    clean_msgs = fleet_messages(SPEC, 6.0, frame=10)
    _, clean = run(clean_msgs)
    victim = "hydro/rig/table4-g3/frame"
    msgs, bad_at, expected = [], [], dict.fromkeys(REJECT_REASONS, 0)
    n = 0
    for key, payload in clean_msgs:
        msgs.append((key, payload))
        if key == victim:
            n += 1
            if n % 2 == 0 and n < 60:  # not after the last frame: no window follows it
                reason, bad = BAD_FRAMES[(n // 2) % len(BAD_FRAMES)]
                msgs.append((key, bad))
                expected[reason] += 1
                bad_at.append(orjson.loads(payload)["seq"] + N - 1)  # after the frame's last sample
    assert n // 2 - 1 >= len(BAD_FRAMES)
    core, got = run(msgs, chunk=64)
    assert core.counters.rejected == expected and core.counters.accepted == 3000
    got, want = by_rig(got), by_rig(clean)
    for rig in SPEC.ids:
        assert_clean_but_flagged(rig, got[rig], want[rig], bad_at if rig == "table4-g3" else [])


# -- the fast decode and the contract model agree ---------------------------------------------------

_num = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64), st.integers(-10**20, 10**20),
                 st.sampled_from([0.0, 1e-3, 5e6, 1e9, -1e9, 10.0, 0.1, 1e3]))


@st.composite
def frames(draw):
    n = draw(st.integers(0, 5))
    obj = {"seq": draw(st.one_of(st.integers(-1, 20), st.just(SEQ_MAX - draw(st.integers(0, 6)))))}
    t0 = draw(st.floats(-10, 10))
    steps = draw(st.lists(st.sampled_from([0.01, 0.0, -0.01]), min_size=n, max_size=n))
    obj["t"] = [t0 + sum(steps[:i + 1]) for i in range(n)]
    for name in ("ug", "x1", "x3", "x4", "x5", "u"):
        if name == "u" and draw(st.booleans()):
            continue
        m = n + draw(st.sampled_from([0, 0, 0, 0, 1, -1])) if n else 0
        obj[name] = draw(st.lists(_num, min_size=max(m, 0), max_size=max(m, 0)))
    return obj


@settings(max_examples=300, deadline=None)
@given(frames())
def test_the_fast_decode_accepts_exactly_what_the_model_accepts(obj):
    try:
        payload = orjson.dumps(obj)
    except orjson.JSONEncodeError:  # an int beyond 64 bits: not a payload a peer can send as JSON here
        return
    try:
        model = parse_frame(orjson.loads(payload))
    except (Rejected, orjson.JSONDecodeError):
        model = None
    try:
        seq, vals, u = decode_frame(payload)
    except Rejected:
        assert model is None
        return
    assert model is not None and seq == model.seq and len(vals) <= FRAME_MAX
    assert vals.tolist() == [list(r) for r in zip(model.t, model.ug, model.x1, model.x3, model.x4, model.x5)]
    assert (u is None) == (model.u is None) and (u is None or u.tolist() == model.u)


def test_frame_payload_is_a_contract_frame():
    p = frame_payload(3, [0.03, 0.04], [[0.1, 0.2], [0.0, 0.0], [1e6, 1e6], [2e6, 2e6], [0.0, 1e-5]], [0.5, 0.6])
    f = Frame.model_validate_json(p)
    assert f.seq == 3 and f.x5 == [0.0, 1e-5] and f.u == [0.5, 0.6]


# -- frames taken a batch at once and one by one agree --------------------------------------------

SHORT = fleet_messages(SPEC, 2.0, frame=10)  # 5 rigs x 20 frames of 10
_FRAMES = {p for k, p in SHORT if k.endswith("/frame")}


def _with_u(payload: bytes) -> bytes:
    d = orjson.loads(payload)
    return orjson.dumps({**d, "u": [0.0] * len(d["t"])})


def _seq_shifted(payload: bytes, by: int) -> bytes:
    d = orjson.loads(payload)
    return orjson.dumps({**d, "seq": d["seq"] + by})


def _corrupted(payload: bytes, how: str) -> bytes:
    """The frame with one thing wrong that the contract refuses (its seq still the right one)."""
    d = orjson.loads(payload)
    if how == "limit":
        d["x3"][-1] = 2e9
    elif how == "time":
        d["t"][3] = d["t"][2]
    elif how == "length":
        d["ug"] = d["ug"][:-1]
    return orjson.dumps(d)


@st.composite
def disturbed_runs(draw):
    """The short fleet's messages with frames dropped, repeated, shifted in seq, carrying the drive,
    swapped with a neighbour, followed by a malformed one or malformed in place, or after a config
    change, and how to cut them into batches."""
    msgs = list(SHORT)
    for _ in range(draw(st.integers(0, 8))):
        i = draw(st.sampled_from([j for j, (_, p) in enumerate(msgs) if p in _FRAMES]))  # a frame as sent
        key, payload = msgs[i]
        what = draw(st.sampled_from(["drop", "repeat", "shift", "u", "swap", "bad", "corrupt", "config"]))
        if what == "drop":
            msgs[i] = (key.replace("/frame", "/health"), b"{}")  # ignored: a gap in the rig's frames
        elif what == "repeat":
            msgs.insert(i + 1, (key, payload))
        elif what == "shift":
            msgs[i] = (key, _seq_shifted(payload, draw(st.sampled_from([-3, 1, 5, 2000]))))
        elif what == "u":
            msgs[i] = (key, _with_u(payload))
        elif what == "swap" and i + 1 < len(msgs):
            msgs[i], msgs[i + 1] = msgs[i + 1], msgs[i]
        elif what == "bad":
            msgs.insert(i + 1, (key, draw(st.sampled_from(BAD_FRAMES))[1]))
        elif what == "config":  # the rig's load changes before this frame: its estimates restart
            config = orjson.loads(dict(SHORT)[key.replace("/frame", "/config")])
            msgs.insert(i, (key.replace("/frame", "/config"), orjson.dumps({**config, "F_L": 3000.0})))
        elif what == "corrupt":
            msgs[i] = (key, _corrupted(payload, draw(st.sampled_from(["limit", "time", "length"]))))
    every = draw(st.sampled_from([2, 7, 25, 60]))  # batch sizes: the frame keys are known after the first
    extra = draw(st.lists(st.integers(1, len(msgs) - 1), max_size=4))
    return msgs, sorted(set(range(every, len(msgs), every)) | set(extra))


@settings(max_examples=25, deadline=None)
@given(disturbed_runs())
def test_frames_taken_a_batch_at_once_give_what_one_by_one_gives(run_and_cuts):
    msgs, cuts = run_and_cuts
    one = MonitorCore(NS, stale_samples=35)  # a gap's stale windows outlast a frame, and batches
    want = [h for m in msgs for h in one.process([m])]  # a lone message always takes the per-message path
    many = MonitorCore(NS, stale_samples=35)
    got = [h for a, b in zip([0, *cuts], [*cuts, len(msgs)]) for h in many.process(msgs[a:b])]
    assert got == want
    assert vars(many.counters) == vars(one.counters)
    assert many.last_seqs().tolist() == one.last_seqs().tolist()
