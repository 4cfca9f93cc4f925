"""The batch health serializer writes, byte for byte, what the contract's dict gives."""

from __future__ import annotations

import numpy as np
import orjson
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from hydromon.contract import PARAM_NAMES, STATUSES, Health
from hydromon.engine.health_json import HealthWriter, health_payload, health_payloads

GRADED = ("B_fv", "f_c", "C_ip", "C_ep", "K_sv_omega_sv2")
P = len(PARAM_NAMES)
FLOATS = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -0.0, 1e-300, 5e-324,
                                                                                    1.7976931348623157e308]))


@st.composite
def batches(draw):
    n = draw(st.integers(0, 6))
    return dict(
        seqs=draw(st.lists(st.integers(0, 2**63 - 1), min_size=n, max_size=n)),
        t=draw(hnp.arrays(np.float64, n, elements=st.floats(-1e12, 1e12))),
        level=draw(hnp.arrays(np.int64, n, elements=st.integers(-1, 4))),
        confidence=draw(hnp.arrays(np.float64, n, elements=FLOATS)),
        params=draw(hnp.arrays(np.float64, (n, P), elements=FLOATS)),
        std_errors=draw(hnp.arrays(np.float64, (n, P), elements=FLOATS)),
        grades=draw(hnp.arrays(np.int64, (n, P), elements=st.integers(-1, 4))),
        statuses=draw(st.lists(st.sampled_from(STATUSES), min_size=n, max_size=n)),
        graded=draw(st.lists(st.sampled_from([GRADED, (), ("K_sv",), PARAM_NAMES]), min_size=n, max_size=n)),
        ranges=draw(st.lists(st.sampled_from([None, "default", "rig-7.json (2026-11-27T10:00:00Z)"]), min_size=n,
                             max_size=n)),
    )


@settings(max_examples=300, deadline=None)
@given(b=batches(), node=st.sampled_from([None, "m1"]), epoch=st.sampled_from([None, 0, 2**40]))
def test_batch_payloads_are_the_dict_payloads_byte_for_byte(b, node, epoch):
    got = health_payloads(**b, node=node, epoch=epoch)
    want = [health_payload(b["seqs"][j], float(b["t"][j]), int(b["level"][j]), float(b["confidence"][j]),
                           b["params"][j].tolist(), b["std_errors"][j].tolist(),
                           b["grades"][j].tolist()[:len(b["graded"][j])], b["statuses"][j], b["graded"][j],
                           b["ranges"][j], node, epoch) for j in range(len(b["seqs"]))]
    assert got == want
    for payload in got:  # and what they give is a valid contract message
        h = Health.model_validate_json(payload)
        assert 0.0 <= h.confidence <= 1.0 and (h.level is None) == (h.grade == "unknown")
        assert all(np.isfinite(v) for v in h.params.values())


def test_non_finite_numbers_are_left_out():
    p = np.full((1, P), 2.5)
    p[0, 3] = np.nan
    s = np.full((1, P), np.inf)
    s[0, 0] = 0.1
    (payload,) = health_payloads([7], np.array([0.07]), np.array([-1]), np.array([np.nan]), p, s,
                                 np.full((1, P), -1), ["converging"], GRADED)
    d = orjson.loads(payload)
    assert d["level"] is None and d["grade"] == "unknown" and d["confidence"] == 0.0
    assert PARAM_NAMES[3] not in d["params"] and len(d["params"]) == P - 1
    assert d["std_errors"] == {PARAM_NAMES[0]: 0.1}


def test_what_the_contract_never_holds_is_refused_not_written():
    p = np.full((1, P), 2.5)
    ok = dict(seqs=[7], t=np.array([0.07]), level=np.array([0]), confidence=np.array([0.5]), params=p,
              std_errors=p, grades=np.zeros((1, P), np.int64), statuses=["ok"], graded=GRADED)
    assert orjson.loads(health_payloads(**ok)[0])["seq"] == 7
    for bad in (dict(seqs=[-1]), dict(level=np.array([5])), dict(grades=np.full((1, P), 9))):
        with pytest.raises(ValueError, match="seqs must be >= 0"):
            health_payloads(**{**ok, **bad})


def test_a_writer_past_its_piece_limit_starts_over_between_batches_not_within_one():
    writer = HealthWriter()
    writer.pieces.limit = 30  # a batch of 40 distinct tags goes past it
    p = np.full((40, P), 1.5)
    for b in range(3):
        tags = [f"rig-{b}-{j}.json" for j in range(40)]
        got = writer.payloads(list(range(40)), np.arange(40) * 0.1, np.zeros(40, np.int64), np.full(40, 0.5), p, p,
                              np.zeros((40, P), np.int64), ["ok"] * 40, GRADED, tags)
        assert got == [health_payload(j, j * 0.1, 0, 0.5, [1.5] * P, [1.5] * P, [0] * len(GRADED), "ok", GRADED,
                                      tags[j]) for j in range(40)]
