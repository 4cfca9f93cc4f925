"""A load offset that a Stribeck hump fitted beside it takes the place of (``monitor.audit.shadow``).
Records from ``hydromon.tools.audit_sweep._record`` (tuning base 11700000, ladder seeds)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from hydromon.tools.audit_sweep import _record
from monitor.audit import AuditOptions, audit
from monitor.audit.shadow import SHADOW, offset_shadow

OFFSET = SimpleNamespace(name="load_offset", score=0.51, effect={"load_offset": 53.0})
HUMP = SimpleNamespace(name="stribeck_friction", score=0.50, effect={"stribeck_F_s": 60.0, "stribeck_v_s": 0.01})


def _pair(offset_beside_hump, f_s=64.0, v_s=0.01):
    calls = []

    def pair(first, second):
        calls.append((first, second))
        return 0.0, None, {"load_offset": offset_beside_hump, "stribeck_F_s": f_s, "stribeck_v_s": v_s}
    return pair, calls


@pytest.mark.parametrize("kept, shadowed", [(0.17, True), (-0.3, True), (SHADOW - 1e-9, True), (SHADOW, False),
                                            (0.98, False), (1.03, False)])
def test_an_offset_is_the_humps_shadow_when_it_keeps_less_than_half_beside_the_hump(kept, shadowed):
    pair, calls = _pair(kept * 53.0)
    got = offset_shadow([OFFSET, HUMP], [OFFSET, HUMP], pair)
    assert calls == [("load_offset", "stribeck_friction")]
    assert bool(got) is shadowed, got
    if shadowed:
        assert set(got) == {"load_offset"} and "falls from 53 N" in got["load_offset"], got


@pytest.mark.parametrize("f_s, v_s", [(0.0, 0.01), (64.0, 0.08)])
def test_no_shadow_of_what_is_no_breakaway_hump(f_s, v_s):
    pair, _ = _pair(9.0, f_s, v_s)
    assert offset_shadow([OFFSET], [OFFSET, HUMP], pair) == {}


def test_no_offset_named_or_no_hump_to_fit_asks_no_joint_fit():
    pair, calls = _pair(9.0)
    assert offset_shadow([HUMP], [OFFSET, HUMP], pair) == {}
    assert offset_shadow([OFFSET], [OFFSET], pair) == {}
    assert calls == []
    assert offset_shadow([OFFSET], [OFFSET, HUMP], lambda a, b: None) == {}


def test_a_hump_the_equations_fit_as_well_as_an_offset_is_named_a_hump():
    """80 N above Coulomb at realistic noise on paper-var (Stribeck ladder, record 86): the
    equations scored a 53 N load offset 0.51 and the hump 0.50, and the offset was named; beside
    the hump the offset falls to 9 N."""
    s, cfg = _record("one", {"stribeck_friction": 80.0}, "paper-var:period=10.331", 0.261, "realistic", 11710086)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.causes == ("stribeck_friction",), (res.causes, res.note)
    assert "the offset falls from 53 N to 9 N" in res.note, res.note


def test_a_load_offset_keeps_its_value_beside_a_hump_and_stays_named():
    """400 N at realistic noise on paper-var (load-offset ladder, record 85): the joint fit keeps
    1.01 of the offset."""
    s, cfg = _record("one", {"load_offset": 400.0}, "paper-var:period=11.079", 0.101, "realistic", 11710085)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.causes == ("load_offset",), (res.causes, res.note)
    assert "falls from" not in res.note, res.note
