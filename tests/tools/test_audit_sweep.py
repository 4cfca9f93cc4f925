"""The audit sweep's record lists (``hydromon.tools.audit_sweep``): what each table counts."""

from __future__ import annotations

from collections import Counter

import pytest

from hydromon.tools.audit_sweep import (BANDS, CLAIMS, CLEAN_SEED, LADDER, LADDER_SEED, NOISES, PROFILES,
                                        _cases, _clean_cases, _ladder_cases, main)


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


def test_ladder_and_clean_seeds_do_not_meet_each_other_or_the_main_sweeps_at_the_same_base():
    assert LADDER_SEED > len(_cases())
    assert CLEAN_SEED > LADDER_SEED + max(len(_ladder_cases(n)) for n in CLAIMS)


def test_clean_repeats_cover_every_profile_band_and_noise_level_including_stress():
    cases = _clean_cases(3)
    cells = Counter((profile, severity, noise) for kind, effects, profile, severity, noise, _ in cases)
    assert set(cells) == {(p, s, n) for p in PROFILES for s in BANDS for n in NOISES + ("stress",)}
    assert set(cells.values()) == {3}
    assert all(kind == "clean" and effects == {} for kind, effects, *_ in cases)


@pytest.mark.parametrize("argv", [["--clean", "0"], ["--clean", "2", "--ladder", "load_offset"]])
def test_a_clean_sweep_of_no_records_or_beside_a_ladder_is_refused(argv, capsys):
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert "--clean takes N >= 1" in capsys.readouterr().err


def test_a_ladder_of_no_known_effect_is_refused(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--ladder", "gravity"])
    assert e.value.code == 2
    assert "invalid choice" in capsys.readouterr().err
