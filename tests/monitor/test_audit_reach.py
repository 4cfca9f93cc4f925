"""A record's Stribeck reach (``monitor.audit.reach``): the smallest hump its motion and noise
would show, given when the audit names nothing but cannot exclude Stribeck friction."""

from __future__ import annotations

import math

import pytest

from hydromon.report.audit import to_json
from hydromon.tools.audit_sweep import _record
from monitor.audit import AuditOptions, audit
from monitor.audit.reach import REACH_GRID


@pytest.fixture(scope="module")
def clean_sine():
    """The paper's sine without noise, new and at fault-grade health (where it slides slowly)."""
    out = {}
    for sev in (0.1, 0.9):
        s, cfg = _record("clean", {}, "paper-id", sev, "none", 41)
        out[sev] = audit(s, cfg, AuditOptions(free_run=False))
    return out


def test_a_clean_records_reach_is_in_its_note_and_its_json(clean_sine):
    res = clean_sine[0.1]
    assert res.cause == "none" and res.stribeck_reach in REACH_GRID, (res.cause, res.stribeck_reach)
    assert f"a hump of at least {res.stribeck_reach:.0f} N above Coulomb (v_s = 10 mm/s)" in res.note, res.note
    assert to_json(res)["stribeck_reach_N"] == res.stribeck_reach


def test_a_slower_sliding_piston_shows_only_a_larger_hump(clean_sine):
    fast, slow = clean_sine[0.1].stribeck_reach, clean_sine[0.9].stribeck_reach
    assert fast <= 40.0 and slow >= 4 * fast, (fast, slow)


@pytest.mark.parametrize("severity", [0.1, 0.9])
def test_a_hump_twice_a_records_reach_is_named_on_that_record(clean_sine, severity):
    f_s = 2 * clean_sine[severity].stribeck_reach
    s, cfg = _record("one", {"stribeck_friction": f_s}, "paper-id", severity, "none", 41)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == "stribeck_friction", (f_s, res.cause, res.note)


def test_no_reach_is_given_when_a_cause_is_named():
    s, cfg = _record("one", {"load_offset": 1000.0}, "steps", 0.3, "realistic", 5)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == "load_offset" and res.stribeck_reach is None
    assert to_json(res)["stribeck_reach_N"] is None


def test_beyond_the_largest_hump_tried_reads_beyond():
    from monitor.audit.decide import _reach_words

    assert "no hump up to 2560 N" in _reach_words(math.inf)
