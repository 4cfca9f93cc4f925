"""Wiring mistakes a record shows (monitor.audit.wiring): a channel that reads one value
throughout and chamber pressures logged the other way round are named, and evaluate, commission
and the audit do not take such a record for a right one."""

import json

import numpy as np
import pytest

from hydromon.cli.main import main
from hydromon.store.csvfile import csv_text
from hydromon.tools.audit_cases import _drawn, _record
from monitor.audit import audit
from monitor.audit.wiring import EXCHANGE_LOG, dead_channels, dead_drive_words, exchange, exchanged_words, wiring_words
from monitor.commission import commission

EXCHANGED = [0, 1, 3, 2, 4]


def _case(kind, profile, noise, seed, duration=20.0):
    p, severity = _drawn(profile, 0.5, seed)
    return _record(kind, {}, p, severity, noise, seed, duration=duration)


@pytest.mark.parametrize("kind", ["ref", "rig"])
@pytest.mark.parametrize("profile", ["paper-id", "paper-var", "steps", "multisine"])
@pytest.mark.parametrize("noise", ["none", "realistic"])
def test_exchanged_pressures_are_named_and_the_record_as_it_is_is_not(kind, profile, noise):
    """Every input shape, the reference rig and a rig of its own size: exchanging x3 and x4 makes
    both the chamber equations and the force balance fit worse, so the exchanged copy is named
    and the record as it is is not."""
    x, cfg = _case(kind, profile, noise, 7)
    as_is = exchange(x, cfg)
    assert as_is is not None and max(as_is.chamber, as_is.force) < -EXCHANGE_LOG and not as_is.called, as_is
    assert exchanged_words(x, cfg) is None
    said = exchanged_words(x[:, EXCHANGED], cfg)
    assert said is not None and said.startswith("x3 and x4 look exchanged: read the other way round"), said


def test_a_record_that_cannot_tell_says_nothing():
    """A rig held still leaves no equations to fit: no opinion, rather than a guess."""
    x, cfg = _case("ref", "steps", "realistic", 7)
    held = np.tile(x[-1], (2000, 1)) + np.random.default_rng(0).normal(0.0, 1e-9, (2000, 5)) * [0, 1, 1e3, 1e3, 0.1]
    assert exchange(held, cfg) is None and wiring_words(held, cfg) is None


@pytest.mark.parametrize("column", [1, 2, 3, 4])
def test_a_dead_channel_is_named_with_its_value(column):
    x, cfg = _case("ref", "paper-var", "realistic", 7)
    x[:, column] = 5e6 if column in (2, 3) else 0.01
    assert [name for name, _ in dead_channels(x)] == [("ug", "x1", "x3", "x4", "x5")[column]]
    said = wiring_words(x, cfg)
    assert said is not None and "in every sample: a sensor that is not logged, stuck" in said, said


def test_the_longest_stretch_is_judged_when_the_record_has_gaps():
    """A gap joins two stretches whose derivatives are not continuous: the check reads the
    longer one (the rest of a record with a 3 s stretch before a gap)."""
    x, cfg = _case("ref", "paper-var", "realistic", 7)
    swapped = x[:, EXCHANGED].copy()
    swapped[:300] = x[:300]  # a stretch wired right before the gap, too short to outvote
    assert wiring_words(swapped, cfg, restarts=(300,)).startswith("x3 and x4 look exchanged")


def test_evaluate_says_an_exchanged_record_is_not_to_be_trusted(tmp_path, capsys):
    """A healthy rig's record with x3 and x4 exchanged was graded health, ok: now bad-input, with
    why and the grade withheld, in the JSON and the exit code."""
    x, cfg = _case("ref", "paper-var", "realistic", 7, duration=30.0)
    t = np.arange(len(x)) / cfg.sample_rate
    (tmp_path / "right.csv").write_text(csv_text(t, x))
    (tmp_path / "exchanged.csv").write_text(csv_text(t, x[:, EXCHANGED]))
    assert main(["evaluate", str(tmp_path / "right.csv"), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["wiring"] is None and got["status"] == "ok", got
    assert main(["evaluate", str(tmp_path / "exchanged.csv"), "--json"]) == 1
    got = json.loads(capsys.readouterr().out)
    assert got["status"] == "bad-input" and got["wiring"].startswith("x3 and x4 look exchanged"), got
    assert got["grade"] == "unknown" and got["level"] is None and got["confidence"] == 0.0, got  # withheld
    main(["evaluate", str(tmp_path / "exchanged.csv")])
    assert "not to be trusted: x3 and x4 look exchanged" in " ".join(capsys.readouterr().out.split())


def test_commission_and_the_audit_refuse_a_miswired_record():
    """Ranges made around exchanged pressures would grade the same miswired rig health for good;
    the audit would judge every model by the wrong pressures."""
    x, cfg = _case("ref", "paper-var", "realistic", 7, duration=30.0)
    with pytest.raises(ValueError, match="^the record's sensors look wired wrong: x3 and x4 look exchanged"):
        commission(x[:, EXCHANGED], cfg, runs=0)
    dead = x.copy()
    dead[:, 2] = 5e6
    with pytest.raises(ValueError, match="^the record's sensors look wired wrong: x3 is 5e\\+06 in every sample"):
        commission(dead, cfg, runs=0)
    with pytest.raises(ValueError, match="^x3 and x4 look exchanged: .*so mend the record first"):
        audit(x[:, EXCHANGED], cfg)


def test_a_dead_valve_drive_is_refused_and_a_held_one_is_not(tmp_path, capsys):
    """A u column of zeros under a moving spool graded the rig health with its valve gain 0 and
    unknown; the drive of a held spool may well be constant."""
    x, cfg = _case("ref", "paper-var", "realistic", 7)
    t = np.arange(len(x)) / cfg.sample_rate
    (tmp_path / "dead-u.csv").write_text(csv_text(t, x, np.zeros(len(x))))
    assert main(["evaluate", str(tmp_path / "dead-u.csv")]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "dead-u.csv: u (the valve drive) is 0 V in every sample that carries it while the spool moves" in err, err
    held = np.tile(x[0], (len(x), 1))
    held[:, 4] += np.random.default_rng(1).normal(0.0, 5e-7, len(x))  # a held spool's sensor noise
    assert dead_drive_words(np.full(len(x), 0.5), held[:, 4], cfg) is None
    assert dead_drive_words(np.full(len(x), 0.5), x[:, 4], cfg) is not None
    # a drive on a few samples only (a second of them) says nothing of the valve
    assert dead_drive_words(np.zeros(100), x[::20, 4][:100], cfg) is None
