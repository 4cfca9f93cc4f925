"""The audit's decision rules (``monitor.audit.decide``) on rankings built by hand: the rule is
what is tested, not whichever record happens to reach it. The equations under the ranking are a
real record's (a clean 10 s paper-var record, realistic noise), so the verdict's structure check
runs as it does in an audit."""

from __future__ import annotations

from functools import lru_cache

import pytest

from hydromon.tools.audit_sweep import _record
from monitor.audit import AuditOptions, CandidateResult
from monitor.audit.decide import decide
from monitor.audit.equations import _Equations


@lru_cache(maxsize=1)
def _equations():
    s, cfg = _record("clean", {}, "paper-var", 0.3, "realistic", 5, duration=10.0)
    return _Equations(s, cfg, 0.7)


def _ranked(*rows):
    """CandidateResults best first from (name, score, free-run gain)."""
    eq = _equations()
    return [CandidateResult(name=name, equation="", value=1.0, score=score, residual_ratio={}, train_ratio={},
                            gain=gain, freerun={}, params=dict(eq.p_nom), effect={name: 1.0})
            for name, score, gain in sorted(rows, key=lambda r: -r[1])]


def _decide(results):
    eq = _equations()
    return decide(results, eq.p_nom, (), eq.nominal, eq.sig, eq.split, eq.cfg, AuditOptions(),
                  pair=lambda first, second: None)


def test_a_tie_that_no_free_run_breaks_names_nothing_and_says_so():
    """Two extensions within the margin of each other (0.85 > 0.6 x 1.0), the winner's free run
    simulating the held-out part no better than the nominal model's: nothing is named."""
    got = _decide(_ranked(("load_offset", 1.0, -0.006), ("entrained_air", 0.85, 0.02)))
    assert got.cause == "none" and not got.confident and got.causes == (), got
    assert "cannot tell load_offset from entrained_air (held-out scores 1.00, 0.85)" in got.note, got.note
    assert "nothing is named" in got.note, got.note


@pytest.mark.parametrize("runner_up, gain, named, confident", [
    (0.85, 0.05, "load_offset", False),  # a tie the winner's free run breaks: named, not confident
    (0.50, -0.006, "load_offset", False),  # no tie; the equations' evidence alone: named, not confident
    (0.50, 0.05, "load_offset", True),  # no tie, borne out by the free run
])
def test_a_winner_is_named_where_its_free_run_breaks_the_tie_or_there_is_none(runner_up, gain, named, confident):
    got = _decide(_ranked(("load_offset", 1.0, gain), ("entrained_air", runner_up, 0.02)))
    assert (got.cause, got.confident) == (named, confident), (got.cause, got.note)


def test_a_candidate_passed_over_for_its_free_run_is_said_so_not_said_to_score_below_its_threshold():
    """A best candidate scoring 10 whose free run diverges is passed over, and the note says why,
    not that it scores below its threshold ("scores 10.02 <= 0.15")."""
    got = _decide(_ranked(("sensor_delay", 10.02, float("-inf")), ("load_offset", 0.05, 0.01)))
    assert got.cause in ("none", "unexplained") and got.causes == (), (got.cause, got.note)
    assert "sensor_delay scores 10.02, but its free run diverges" in got.note, got.note
    assert "<=" not in got.note, got.note


def test_a_free_run_that_cannot_be_compared_is_said_so():
    from monitor.audit.verdict import passed_over_words

    c = _ranked(("load_offset", 7.75, float("nan")))[0]
    assert passed_over_words(c) == ("load_offset scores 7.75, but its free run cannot be compared with the "
                                     "nominal model's, whose error is not finite")
