"""Validation at the edge: a sample is taken exactly when the contract's model takes it, by the fast path and the batch decoder alike."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import orjson
import pytest
from hypothesis import event, example, given, settings
from hypothesis import strategies as st

from hydromon.contract import SAMPLE_LIMITS, SEQ_MAX, Sample
from hydromon.engine.samples import sim_samples
from hydromon.engine.validate import REJECT_REASONS, VALUE_LIMITS, Rejected, parse_sample

_FLOAT_FIELDS = ("t", "ug", "x1", "x3", "x4", "x5")


_SAMPLE_FIELDS = ("seq", *_FLOAT_FIELDS)


_FINITE = st.floats(allow_nan=False, allow_infinity=False)


def _in_range(field: str):
    """Valid floats of a float field of the contract (t is unbounded, the rest within SAMPLE_LIMITS)."""
    lim = SAMPLE_LIMITS.get(field)
    return _FINITE if lim is None else st.floats(-lim, lim)


def _beyond(field: str):
    """Finite numbers outside a field's range (bad-value)."""
    if field == "seq":  # just beyond either end, or anywhere beyond (orjson still encodes up to 2**64 - 1)
        return st.integers(-3, -1) | st.integers(SEQ_MAX + 1, SEQ_MAX + 3) | st.integers(-2**63, -1) | \
            st.integers(SEQ_MAX + 1, 2**64 - 1)
    lim = SAMPLE_LIMITS[field]
    mag = st.just(math.nextafter(lim, math.inf)) | st.floats(lim, exclude_min=True, allow_infinity=False) | \
        st.integers(int(lim) + 1, 10**18)
    return st.tuples(st.sampled_from([1, -1]), mag).map(lambda sm: sm[0] * sm[1])


# mutation kind -> (the reason it is rejected for, None: still a valid sample; the fields it applies to)
_MUTATIONS = {
    "drop": ("missing-field", _SAMPLE_FIELDS),
    "unknown": ("unknown-field", ()),  # adds a field
    "non-finite": ("non-finite", _FLOAT_FIELDS),  # (a NaN seq is a wrong type: not an integer)
    "wrong-type": ("wrong-type", _SAMPLE_FIELDS),
    "out-of-range": ("bad-value", ("seq", *SAMPLE_LIMITS)),  # t has no range
    "int": (None, _FLOAT_FIELDS),  # an integer where a float is due: the contract takes it as that float
}


def _outcome(obj):
    """The contract model's verdict: ``(seq, t, ug, x1, x3, x4, x5)`` it accepts, or None."""
    try:
        s = Sample.model_validate(obj)
    except ValueError:
        return None
    return (s.seq, s.t, s.ug, s.x1, s.x3, s.x4, s.x5)


@st.composite
def mutated_samples(draw):
    """``(payload dict, kinds of mutation applied)``: a valid contract sample (what the sim
    sends: an int seq and six finite floats in range) with 0-2 mutations on distinct fields."""
    obj = {"seq": draw(st.integers(0, SEQ_MAX))}
    obj.update({k: draw(_in_range(k)) for k in _FLOAT_FIELDS})
    n = draw(st.sampled_from((0, 1, 2, 1, 2)))  # (integers(0, 2) drew 0 in over half the examples)
    kinds = draw(st.lists(st.sampled_from(sorted(_MUTATIONS)), min_size=n, max_size=n))
    used: set[str] = set()
    for kind in kinds:
        if kind == "unknown":
            obj[draw(st.sampled_from(["extra", "z", "X1", "seq_", ""]))] = draw(st.none() | _FINITE | st.text(max_size=3))
            continue
        f = draw(st.sampled_from([f for f in _MUTATIONS[kind][1] if f not in used]))
        used.add(f)
        if kind == "drop":
            del obj[f]
        elif kind == "non-finite":
            obj[f] = draw(st.sampled_from([math.nan, math.inf, -math.inf, "nan", "inf", "-Infinity", "NaN"]))
        elif kind == "wrong-type":
            other = st.floats() if f == "seq" else st.sampled_from(["1.5", "", "abc"])  # a float seq is wrong
            obj[f] = draw(st.booleans() | st.none() | other | st.just([1.0]))
        elif kind == "out-of-range":
            obj[f] = draw(_beyond(f))
        else:  # int
            lim = int(SAMPLE_LIMITS.get(f, 10**18))
            obj[f] = draw(st.integers(-lim, lim))
    return obj, kinds


def test_parse_sample_accepts_exactly_what_the_contract_model_accepts():
    """Valid samples with 0-2 mutations (drop a field, an unknown field, a non-finite value, a
    wrong type, a value out of range, an int for a float): parse_sample gives the model's values
    field by field (so its fast paths are checked) or rejects for the mutation's reason, and the
    batch decoder of the regular path (``sim_samples``) never takes what the contract rejects.
    Every outcome is reached (asserted after the run)."""
    seen: Counter = Counter()

    # One explicit case per outcome, so each is checked in every run: a random run can reach no
    # bad-value in 300 draws (it has happened in CI) though typical runs reach 18-50.
    valid = {"seq": 7, "t": 0.07, "ug": 2.0, "x1": 0.01, "x3": 4.0e6, "x4": 2.0e6, "x5": 1.0e-5}
    @settings(max_examples=300, deadline=None)
    @example(case=(dict(valid), []))
    @example(case=({**valid, "x1": 1}, ["int"]))
    @example(case=({k: v for k, v in valid.items() if k != "x3"}, ["drop"]))
    @example(case=({**valid, "extra": 1.0}, ["unknown"]))
    @example(case=({**valid, "x4": math.nan}, ["non-finite"]))
    @example(case=({**valid, "ug": "abc"}, ["wrong-type"]))
    @example(case=({**valid, "x5": -1e300}, ["out-of-range"]))
    @given(case=mutated_samples())
    def check(case):
        obj, kinds = case
        reasons = [_MUTATIONS[k][0] for k in kinds if _MUTATIONS[k][0] is not None]
        expected = min(reasons, key=REJECT_REASONS.index) if reasons else None
        want = _outcome(obj)
        assert (want is None) == (expected is not None), (obj, kinds)
        try:
            got = parse_sample(obj)
        except Rejected as exc:
            assert want is None and exc.reason == expected, (obj, kinds, exc)
            got = None
        payload = orjson.dumps(obj)  # NaN and inf come out as null: still not a valid sample
        # the batch decoder: a batch it decodes whole, and one it falls back to one by one for
        alone, batch = sim_samples([payload, payload]), sim_samples([payload, b"{bad"])
        if want is None:
            assert got is None
            # what the regular path may take of a rejected payload: nothing, or values beyond
            # VALUE_LIMITS, which MonitorCore sends to parse_sample (and so to bad-value)
            for tup in (alone[0], batch[0]):
                assert tup is None or (expected == "bad-value" and (np.abs(tup[2:]) > VALUE_LIMITS).any()), (obj, tup)
            outcome = expected
        else:
            assert got == want, (obj, got, want)  # every field, in the contract's order
            assert [type(v) for v in got] == [int] + [float] * 6
            assert alone == [want, want] and batch == [want, None]
            fast = all(type(obj[k]) is float for k in _FLOAT_FIELDS)
            outcome = "accepted (floats)" if fast else "accepted (ints)"
        event(outcome)
        seen[outcome] += 1

    check()
    # both branches, both of parse_sample's fast paths and every reason a sample is rejected for
    # (the reasons for keys and JSON are not about a decoded sample)
    assert set(seen) == {"accepted (floats)", "accepted (ints)", "non-finite", "missing-field", "wrong-type",
                         "unknown-field", "bad-value"}, seen


def test_parse_sample_and_the_batch_decoder_give_every_field_of_valid_samples():
    """Deterministic: distinct values in every field, through both fast paths of parse_sample
    and the batch decoder of the regular path, equal the contract model's, field by field."""
    floats = {"seq": 12, "t": 0.12, "ug": 1.5, "x1": -0.02, "x3": 5.5e6, "x4": 4.25e6, "x5": 2e-5}
    ints = {"seq": 13, "t": 1, "ug": -2, "x1": 0, "x3": 7000000, "x4": 3000000, "x5": 0}
    limits = {"seq": SEQ_MAX, "t": -1e300, **{k: -v for k, v in SAMPLE_LIMITS.items()}}
    cases = [floats, ints, limits, {**floats, "x3": 1, "x5": 0.0}]
    want = [(d["seq"], *(float(d[k]) for k in _FLOAT_FIELDS)) for d in cases]
    assert want == [_outcome(d) for d in cases]
    assert [parse_sample(d) for d in cases] == want
    assert [parse_sample(orjson.loads(orjson.dumps(d))) for d in cases] == want
    assert sim_samples([orjson.dumps(d) for d in cases]) == want
    # one payload the batch decoder refuses: the rest still come out, one by one
    assert sim_samples([orjson.dumps(d) for d in cases] + [b"[]"]) == want + [None]


@pytest.mark.parametrize("ints", [False, True], ids=["floats", "ints"])
def test_parse_sample_rejects_values_just_beyond_the_contracts_ranges(ints):
    """Deterministic: the edges of the ranges, through both fast paths of parse_sample (six
    floats; ints) and the batch decoder (the property test above reaches them only now and then)."""
    base = {"seq": 5, "t": 0.05, "ug": 0.1, "x1": 0.01, "x3": 5e6, "x4": 6e6, "x5": 1e-5}
    if ints:
        base = {**base, "t": 5, "ug": 1, "x1": 0, "x3": 5000000, "x4": 6000000, "x5": 0}
    good = [{**base, "seq": 0}, {**base, "seq": SEQ_MAX}]
    bad_seq = [{**base, "seq": s} for s in (-1, -2, -3, -2**63, SEQ_MAX + 1, SEQ_MAX + 3)]
    bad_val = []
    for k, lim in SAMPLE_LIMITS.items():
        good += [{**base, k: lim}, {**base, k: -lim}]
        beyond = (int(lim) + 1, -int(lim) - 1) if ints and lim >= 1 else \
            (math.nextafter(lim, math.inf), -math.nextafter(lim, math.inf))
        bad_val += [{**base, k: v} for v in beyond]
    assert [parse_sample(d) for d in good] == [_outcome(d) for d in good]
    assert sim_samples([orjson.dumps(d) for d in good]) == [_outcome(d) for d in good]
    for d in bad_seq + bad_val:
        assert _outcome(d) is None
        with pytest.raises(Rejected) as exc:
            parse_sample(d)
        assert exc.value.reason == "bad-value", d
    for d in bad_seq:  # the batch decoder refuses seqs out of range, alone and in a batch
        assert sim_samples([orjson.dumps(d)]) == [None], d
        assert sim_samples([orjson.dumps(good[0]), orjson.dumps(d)]) == [_outcome(good[0]), None], d
    # values beyond their limits it leaves to the caller (MonitorCore checks VALUE_LIMITS)
    for tup in sim_samples([orjson.dumps(d) for d in bad_val]):
        assert (np.abs(tup[2:]) > VALUE_LIMITS).any()


def test_an_unknown_field_whose_value_reads_as_infinity_is_an_unknown_field():
    # found by the property above in CI: {"extra": "INF"} was rejected as non-finite
    ok = {"seq": 0, "t": 0.0, "ug": 0.0, "x1": 0.0, "x3": 0.0, "x4": 0.0, "x5": 0.0}
    with pytest.raises(Rejected) as info:
        parse_sample({**ok, "extra": "INF"})
    assert info.value.reason == "unknown-field"


def test_an_integer_beyond_any_double_is_rejected_not_raised():
    ok = {"seq": 0, "t": 0.0, "ug": 0.0, "x1": 0.0, "x3": 0.0, "x4": 0.0, "x5": 0.0}
    with pytest.raises(Rejected) as info:
        parse_sample({**ok, "t": 10 ** 400})  # was an OverflowError out of the model
    assert info.value.reason == "non-finite"
