"""The audit sweep's record lists (``hydromon.tools.audit_sweep``): what each table counts."""

from __future__ import annotations

from collections import Counter

import pytest

from hydromon.tools.audit_sweep import (BANDS, CLAIMS, CLEAN_SEED, LADDER, LADDER_SEED, NOISES, PAIR_SEED, PAIRS,
                                        PROFILES, _cases, _clean_cases, _ladder_cases, _pair_cases, main)


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


def test_pair_repeats_cover_every_pair_profile_and_band_at_realistic_noise():
    cases = _pair_cases(2)
    cells = Counter((tuple(sorted(effects.items())), profile, sev) for _, effects, profile, sev, _, _ in cases)
    assert set(cells) == {(tuple(sorted({a: va, b: vb}.items())), p, s) for a, va, b, vb in PAIRS for p in PROFILES
                          for s in BANDS}
    assert set(cells.values()) == {2}
    assert all(kind == "pair" and noise == "realistic" for kind, _, _, _, noise, _ in cases)
    assert PAIR_SEED > CLEAN_SEED + len(_clean_cases(5))  # --clean 5 and --pairs N never share a seed


@pytest.mark.parametrize("argv, said", [
    (["--pairs", "0"], "--pairs takes N >= 1"), (["--pairs", "1", "--clean", "1"], "--pairs takes N >= 1"),
    (["--pairs", "1", "--ladder", "load_offset"], "--pairs takes N >= 1"), (["--rigs", "0"], "--rigs takes N >= 1"),
    (["--rigs", "1", "--pairs", "1"], "--rigs takes N >= 1"),
    (["--rigs", "1", "--ladder", "load_offset"], "--rigs takes N >= 1")])
def test_a_pair_or_rig_sweep_of_no_records_or_beside_another_sweep_is_refused(argv, said, capsys):
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert said in capsys.readouterr().err


def test_a_pair_sweep_counts_both_effects_named_per_profile_and_band(monkeypatch, capsys):
    from hydromon.tools import audit_sweep

    def audit_one(args):  # right when the record's band is not the fault band: 48 of 60
        i, case, seed, fixed, duration, steps = args
        truth = sorted(case[1])
        return i, (truth if case[3] < 0.8 else ["none"]), truth, "", case[2]
    monkeypatch.setattr(audit_sweep, "_audit_one", audit_one)
    main(["--pairs", "1", "--seed-base", "5"])
    out = capsys.readouterr().out
    assert "two effects (both named): 48/60 right" in out
    assert "| entrained_air 0.04 + load_offset 800 | 4/5 | 4/5 | 4/5 | 4/5 | 16/20 |" in out  # by profile
    assert "| entrained_air 0.04 + load_offset 800 | 4/4 | 4/4 | 4/4 | 4/4 | 0/4 | 16/20 |" in out  # by band
    assert "base 5 (seeds base + 30000 + index)" in out


def test_clean_repeats_cover_every_profile_band_and_noise_level_including_stress():
    cases = _clean_cases(3)
    cells = Counter((profile, severity, noise) for kind, effects, profile, severity, noise, _ in cases)
    assert set(cells) == {(p, s, n) for p in PROFILES for s in BANDS for n in NOISES + ("stress",)}
    assert set(cells.values()) == {3}
    assert all(kind == "clean" and effects == {} for kind, effects, *_ in cases)


def test_clean_records_take_the_noise_levels_asked_for():
    cases = _clean_cases(1, ("pct:0.01", "pct:0.02"))
    assert Counter(noise for *_, noise, _ in cases) == {"pct:0.01": 20, "pct:0.02": 20}


@pytest.mark.parametrize("argv, said", [(["--clean", "1", "--noise", "realistic,loud"], "unknown noise model 'loud'"),
                                        (["--noise", "pct:0.01"], "--noise goes with --clean"),
                                        (["--clean", "1", "--noise", "pct:150"], "--noise")])
def test_a_noise_level_that_is_not_one_or_without_clean_records_is_refused(argv, said, capsys):
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert said in capsys.readouterr().err


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


def test_a_records_input_and_health_are_drawn_from_its_seed_within_its_band():
    from plant_sim.degradation import grade_of_severity
    from plant_sim.profiles import parse_profile

    from hydromon.tools.audit_sweep import SEV_JITTER, _drawn

    for profile in PROFILES:
        for sev in BANDS:
            draws = [_drawn(profile, sev, seed) for seed in range(8100000, 8100040)]
            assert _drawn(profile, sev, 8100000) == draws[0]  # a pure function of the seed
            assert len({spec for spec, _ in draws}) == len(draws)  # every seed its own input
            for spec, s in draws:
                assert parse_profile(spec).name == profile
                assert abs(s - sev) <= SEV_JITTER + 1e-9
                assert grade_of_severity(s) == grade_of_severity(sev)
    with pytest.raises(ValueError, match="chirp"):
        _drawn("chirp", 0.1, 1)


def test_a_drawn_record_differs_from_the_fixed_one_without_noise():
    """Noise-free records on the default inputs are the same for every seed; drawn ones are not."""
    import numpy as np

    from hydromon.tools.audit_sweep import _drawn, _record

    fixed = [_record("clean", {}, "steps", 0.5, "none", seed, duration=2.0)[0] for seed in (1, 2)]
    assert np.array_equal(fixed[0], fixed[1])
    drawn = [_record("clean", {}, *_drawn("steps", 0.5, seed), "none", seed, duration=2.0)[0] for seed in (1, 2)]
    assert not np.array_equal(drawn[0], drawn[1])


@pytest.mark.parametrize("duration", ["2", "nan", "-20"])
def test_a_record_length_below_five_seconds_is_refused(duration, capsys):
    with pytest.raises(SystemExit) as e:
        main(["--ladder", "load_offset", "--duration", duration])
    assert e.value.code == 2
    assert "--duration must be at least 5 s" in capsys.readouterr().err


def test_the_record_length_reaches_every_record(monkeypatch):
    from hydromon.tools import audit_sweep

    asked = []

    class Stop(Exception):
        pass

    def record(kind, effects, profile, severity, noise, seed, duration=audit_sweep.DURATION):
        asked.append(duration)
        raise Stop

    monkeypatch.setattr(audit_sweep, "_record", record)
    with pytest.raises(Stop):
        main(["--ladder", "load_offset", "--duration", "60"])
    assert asked == [60.0]


def test_rig_records_cover_every_effect_and_clean_on_every_profile_band_and_noise():
    from hydromon.tools.audit_sweep import RIG_MULTIPLE, RIG_SEED, _rig_cases

    cases = _rig_cases(2)
    cells = Counter((tuple(effects), profile, severity, noise) for kind, effects, profile, severity, noise, _ in cases)
    assert set(cells) == {(w, p, s, n) for w in [(), *((name,) for name in CLAIMS)] for p in PROFILES
                          for s in BANDS for n in NOISES}
    assert set(cells.values()) == {2}
    for kind, effects, _, _, noise, _ in cases:
        assert kind == "rig"
        assert all(v == RIG_MULTIPLE * CLAIMS[name][1][noise] for name, v in effects.items())
    assert RIG_SEED > PAIR_SEED + len(_pair_cases(5))  # --pairs 5 and --rigs N never share a seed


def test_a_magnitude_scales_to_the_rig_and_stays_on_the_reference_rig():
    from hydromon.contract import RigConfig
    from plant_sim.params import PlantParams

    from hydromon.tools.audit_cases import _scaled

    ref, plant = RigConfig(), PlantParams()
    for name in CLAIMS:
        assert _scaled(name, 3.0, ref, plant) == pytest.approx(3.0)
    big = ref.model_copy(update={"A1": 2 * ref.A1, "p_s": 1.5 * ref.p_s})
    assert _scaled("load_offset", 100.0, big, plant) == pytest.approx(300.0)  # 3x the largest force
    assert _scaled("stribeck_friction", 30.0, big, plant) == pytest.approx(90.0)
    assert _scaled("supply_pressure_sag", 1e10, big, plant) == pytest.approx(0.75e10)  # p_s / A1
    # twice the area at 1.5 times the supply: the same speed takes 2 / sqrt(1.5) the spool opening
    assert _scaled("valve_dead_band", 10.0, big, plant) == pytest.approx(10.0 * 2 / 1.5 ** 0.5)
    assert _scaled("entrained_air", 0.04, big, plant) == 0.04
    assert _scaled("sensor_delay", 3, big, plant) == 3


def test_a_rig_record_runs_on_a_rig_of_its_own_drawn_from_its_seed():
    import numpy as np

    from hydromon.contract import RigConfig
    from hydromon.tools.audit_sweep import _record

    (s1, c1), (s2, c2) = (_record("rig", {}, "steps", 0.5, "none", seed, duration=2.0) for seed in (1, 2))
    assert c1 != RigConfig() and c2 != c1
    assert not np.array_equal(s1, s2)
    again, c_again = _record("rig", {}, "steps", 0.5, "none", 1, duration=2.0)
    assert c_again == c1 and np.array_equal(again, s1)
    offset, _ = _record("rig", {"load_offset": 400.0}, "steps", 0.5, "none", 1, duration=2.0)
    assert not np.array_equal(offset, s1)  # the same rig, with the offset
    assert _record("clean", {}, "steps", 0.5, "none", 1, duration=2.0)[1] == RigConfig()


def test_a_rig_sweep_counts_each_effect_and_the_clean_records_per_profile(monkeypatch, capsys):
    from hydromon.tools import audit_sweep

    def audit_one(args):  # right except in the fault band: 4 of 5 per cell
        i, case, seed, fixed, duration, steps = args
        truth = sorted(case[1]) or ["none"]
        return i, (truth if case[3] < 0.8 else ["unexplained"]), truth, "", case[2]
    monkeypatch.setattr(audit_sweep, "_audit_one", audit_one)
    main(["--rigs", "1", "--seed-base", "5"])
    out = capsys.readouterr().out
    assert "| none | clean | - | 4/5 | 4/5 | 4/5 | 4/5 | 16/20 |" in out
    assert "| realistic | load_offset | 1600 N | 4/5 | 4/5 | 4/5 | 4/5 | 16/20 |" in out
    assert "one effect: 224/280 right" in out and "clean (named 'none'): 32/40 right" in out
    assert "base 5 (seeds base + 40000 + index)" in out


@pytest.mark.parametrize("spec, said", [("x1=0", "'x1=0': the step must be finite and > 0"),
                                        ("q=1", "'q=1': round ug, x1, p (both pressures) or x5"),
                                        ("x1=um", "'x1=um': the step must be a number (SI units)")])
def test_a_rounding_of_no_channel_or_no_step_is_refused(spec, said, capsys):
    with pytest.raises(SystemExit) as e:
        main(["--round", spec, "--quick"])
    assert e.value.code == 2 and f"--round: {said}" in capsys.readouterr().err


def test_rounding_writes_the_named_channels_in_whole_steps_and_leaves_the_rest():
    import numpy as np

    from hydromon.tools.audit_sweep import _parse_round, _rounded

    s = np.random.default_rng(1).normal(size=(50, 5)) * [1.0, 1e-3, 1e6, 1e6, 1e-4]
    r = _rounded(s, _parse_round("x1=1e-4, p=400"))
    np.testing.assert_allclose(r[:, 1] / 1e-4, np.round(r[:, 1] / 1e-4), atol=1e-9)
    np.testing.assert_allclose(r[:, 2:4] / 400, np.round(r[:, 2:4] / 400), atol=1e-9)
    assert np.array_equal(r[:, [0, 4]], s[:, [0, 4]]) and np.abs(r - s).max() <= 200.0
    assert _rounded(s, {}) is s


def test_a_screen_audits_nothing_and_says_how_far_the_records_stand_from_the_refusals(capsys):
    main(["--screen", "--quick", "--ladder", "load_offset", "--seed-base", "5"])
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("23 records screened in ") and out[0].endswith(" s (nothing audited)"), out[0]
    heads = [line.split(":")[0].strip() for line in out[1:5] + out[10:12]]
    assert heads == ["x1", "x3", "x4", "x5", "fitting part", "held-out part"], out
    ranges = [line.split(" times ")[0].strip() for line in out[5:10]]
    assert [r.rsplit(" ", 1)[0] for r in ranges] == [
        "x1 peaks at", "x5 peaks at", "the pressures peak at", "the lower pressure peaks at",
        "the lowest pressure reading is"], out
    assert all(0.0 < float(r.rsplit(" ", 1)[1]) < 10.0 for r in ranges), out
    assert out[-2:] == ["  mended by the outlier gate first: 0 sample(s) in 0 record(s)", "  refused: 0 of 23"]


def test_a_screen_says_so_when_no_record_has_an_excursion_of_a_channel(capsys):
    from hydromon.tools.audit_sweep import _print_screen

    cases = [("clean", {}, "steps", 0.1, "none", None)] * 2
    ranges = {"x1": 0.5, "x5": 0.5, "p": 0.9, "p_peak": 0.4, "p_low": 0.01}
    screened = {i: ([2.0 + i, 3.0, None, 60.0 * i], ((50.0, 40.0), (50.0, 40.0)), "steps", 0, ranges, False)
                for i in range(2)}
    _print_screen(cases, screened, 1.0)
    out = capsys.readouterr().out.splitlines()
    assert out[1].startswith("  x1: largest excursion 3.0 times"), out[1]
    assert out[1].endswith("record 1 (clean steps, noise none)"), out[1]
    assert out[3] == "  x4: no excursion in any record (refused above 50)", out[3]
    assert out[-1] == "  refused: 1 of 2", out  # x5's 60 is past the glitch ratio
