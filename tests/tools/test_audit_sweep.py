"""The audit sweep's record lists (``hydromon.tools.audit_sweep``): what each table counts."""

from __future__ import annotations

from collections import Counter

import pytest

from hydromon.tools.audit_sweep import (BANDS, CLAIMS, LADDER, LADDER_SEED, NOISES, PROFILES, _cases,
                                        _ladder_cases, main)


@pytest.mark.parametrize("name", sorted(CLAIMS))
def test_a_ladder_puts_every_multiple_of_the_claim_on_every_profile_band_and_noise(name):
    cases = _ladder_cases(name)
    assert len(cases) == len(NOISES) * len(LADDER) * len(PROFILES) * len(BANDS)
    cells = Counter((noise, effects[name] / CLAIMS[name][1][noise], profile)
                    for kind, effects, profile, severity, noise, step in cases)
    assert set(cells.values()) == {len(BANDS)}
    assert {m for _, m, _ in cells} == set(LADDER)
    assert {(p, s) for _, _, p, s, _, _ in cases} == {(p, s) for p in PROFILES for s in BANDS}
    assert all(kind == "one" and list(effects) == [name] for kind, effects, *_ in cases)


def test_ladder_seeds_do_not_meet_the_main_sweeps_at_the_same_base():
    assert LADDER_SEED > len(_cases())


def test_a_ladder_of_no_known_effect_is_refused(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--ladder", "gravity"])
    assert e.value.code == 2
    assert "invalid choice" in capsys.readouterr().err
