"""What the audit refuses before it fits anything: a dead sensor, a glitch, a channel in other units,
a rig held at one command (``monitor.audit.auditable``). Each refusal says what, where and what to give instead; a
moving rig's record of any profile, band and noise level is never refused."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hydromon.contract import CHANNELS
from monitor.audit import AuditOptions, audit
from monitor.audit.auditable import (EXCITATION, GLITCH, STILL, excitation_ratios, find_glitch, largest_excursion,
                                     require_auditable, require_excitation, require_live_channels, require_no_glitch)
from monitor.readings import RANGE



@lru_cache(maxsize=None)
def _rec(profile="paper-var", noise="realistic", severity=0.3, kind="clean", seed=5, duration=10.0):
    from hydromon.tools.audit_cases import _record

    s, cfg = _record(kind, {}, profile, severity, noise, seed, duration=duration)
    s.setflags(write=False)
    return s, cfg


def _require(s, cfg, fraction=0.7):
    require_auditable(s, cfg, int(fraction * len(s)))


@pytest.mark.parametrize("profile", ["paper-id", "paper-var", "steps", "multisine"])
@pytest.mark.parametrize("noise", ["none", "realistic", "stress"])
@pytest.mark.parametrize("severity, kind", [(0.05, "clean"), (0.95, "clean"), (0.5, "rig")])
def test_a_moving_rig_of_any_profile_band_and_noise_level_is_taken(profile, noise, severity, kind):
    s, cfg = _rec(profile, noise, severity, kind, seed=7)
    _require(s, cfg)
    for k in range(1, 5):
        assert find_glitch(s[:, k], 200) is None, CHANNELS[k]
    assert all(asked > EXCITATION for asked, _ in excitation_ratios(s, cfg.K_f, int(0.7 * len(s))))


@settings(max_examples=40, deadline=None)
@given(channel=st.integers(1, 4), at=st.integers(0, 999), length=st.integers(1, 150),
       times=st.floats(80.0, 1e4), sign=st.sampled_from([-1.0, 1.0]))
def test_a_spike_or_dropout_of_any_measured_channel_is_refused_where_it_is(channel, at, length, times, sign):
    """A reading that leaves its course by ``times`` the largest step of the channel and comes back
    up to 1.5 s later: refused, naming the channel and the first sample off course."""
    s0, cfg = _rec()
    s = np.array(s0)
    length = min(length, len(s) - 1 - at)
    if at == 0 or length < 1:
        return  # an excursion must leave a course and come back to it inside the record
    s[at:at + length, channel] += sign * times * np.abs(np.diff(s0[:, channel])).max()
    with pytest.raises(ValueError, match=f"^{CHANNELS[channel]} jumps ") as err:
        require_no_glitch(s, cfg.h)
    assert f"at sample {at} " in str(err.value) or f"from sample {at} to {at + length - 1} " in str(err.value)
    assert "cut the record before or after it, or mend those samples" in str(err.value)


def test_a_glitch_is_measured_against_the_channel_s_own_steps():
    """Both steps must exceed GLITCH times the 99th-percentile step; a quantized sensor at rest
    toggling one count is measured against its count, not refused."""
    x = np.sin(np.linspace(0.0, 20.0, 2000))
    q = np.quantile(np.abs(np.diff(x)), 0.99)
    for size, found in ((0.9 * GLITCH * q, False), (1.1 * GLITCH * q, True)):
        y = x.copy()
        y[700] += size
        g = find_glitch(y, 200)
        assert (g is not None) == found, size
        if found:
            assert g[:2] == (700, 701) and g[2] == pytest.approx(size + x[700] - x[699])
    toggling = np.zeros(2000)
    toggling[[100, 900, 1500]] = 1e-6  # one count of a 1 um encoder, 99 % of steps 0
    assert find_glitch(toggling, 200) is None
    toggling[1200] = 1e-3
    assert find_glitch(toggling, 200)[:2] == (1200, 1201)
    assert find_glitch(np.zeros(10), 200) is None and largest_excursion(np.zeros(10), 200) is None


@pytest.mark.parametrize("noise", ["none", "realistic", "stress"])
def test_a_rig_held_at_one_command_is_refused_for_the_part_that_fits(noise):
    """A rig held still was named a 12-sample sensor delay, confident, by how the free runs came to
    rest: the command must move the rig in both parts."""
    s, cfg = _rec("steps:low=2.5,high=2.5", noise)
    with pytest.raises(ValueError, match=r"^the rig is held at one command in the fitting part "
                                         r"\(t = 0.00-6.99 s\): the command ug stays at 2.5 V"):
        _require(s, cfg)
    with pytest.raises(ValueError, match="held at one command in the fitting part"):
        audit(s, cfg)


@pytest.mark.parametrize("mutate, said", [
    (lambda s: s[:, 0].fill(2.5), "the rig is held at one command in the fitting part (t = 0.00-6.99 s): the command "
                                  "ug stays at 2.5 V"),
    (lambda s: s[:, 0].__imul__(1e-6), "the command asks for almost no motion in the fitting part (t = 0.00-6.99 s) "
                                       "while the rig moves"),
    (lambda s: s[:, 1].__iadd__(np.random.default_rng(1).normal(0.0, 0.02, len(s))),
     "too little motion above the position noise in the fitting part (t = 0.00-6.99 s)"),
])
def test_the_refusal_says_whether_the_command_holds_is_out_of_scale_or_drowns_in_x1_s_noise(mutate, said):
    """A command at one value, a command in microvolts under a moving rig (ug in other units), an
    x1 with 20 mm of noise: three records that show no motion to audit, each said for what it is."""
    s0, cfg = _rec()
    s = np.array(s0)
    mutate(s)
    with pytest.raises(ValueError) as err:
        _require(s, cfg)
    assert str(err.value).startswith(said), str(err.value)


def test_a_command_that_stops_in_the_held_out_part_is_refused_for_that_part():
    s0, cfg = _rec()
    s = np.array(s0)
    s[600:, 0] = s[600, 0]  # the command holds from t = 6 s: the held-out part starts at 7 s
    _require(s, cfg, fraction=0.5)  # a second of the held-out part moves
    with pytest.raises(ValueError, match=r"held at one command in the held-out part \(t = 7.00-9.99 s\): the command "
                                         r"ug stays at"):
        _require(s, cfg)


@settings(max_examples=40, deadline=None)
@given(rms=st.floats(0.0, 3.0 * EXCITATION), fraction=st.floats(0.2, 0.9), moves=st.booleans())
def test_a_part_is_held_when_its_command_asks_for_no_more_motion_than_the_noise(rms, fraction, moves):
    """ug / K_f's rms over each part against x1's noise rms (1 um here): held at or below 1 time it;
    up to EXCITATION times it only while x1 moves no more either (a small command under a piston
    that moves 100 times its noise is x1 in other units, or another K_f: the fit shows that)."""
    from monitor.audit.signals import _d4_sigma

    rng = np.random.default_rng(3)
    n, K_f, noise = 1000, 40.0, 1e-6
    s = np.column_stack([np.zeros(n), rng.normal(0, noise, n), 4e6 + rng.normal(0, 1e3, n),
                         7e6 + rng.normal(0, 1e3, n), rng.normal(0, 1e-6, n)])
    if moves:
        s[:, 1] += 100 * noise * np.sqrt(2) * np.sin(np.arange(n) * 0.05)
    split = int(fraction * n)
    s[:, 0] = rms * noise * K_f * np.where(np.arange(n) % 2, 1.0, -1.0)  # rms exactly rms * noise as a position
    limit = (STILL if moves else EXCITATION) * float(_d4_sigma(np.diff(s[:, 1], 4)))
    if rms * noise > limit * 1.01:
        require_excitation(s, K_f, split, 0.01)
    elif rms * noise < limit * 0.99:
        with pytest.raises(ValueError, match=r"(held at one command|too little motion above the position noise|"
                                             r"asks for almost no motion) in the fitting part \(t = "):
            require_excitation(s, K_f, split, 0.01)


@settings(max_examples=25, deadline=None)
@given(dead=st.sets(st.sampled_from([1, 2, 3, 4]), min_size=1), value=st.floats(-1e7, 1e7), seed=st.integers(0, 999))
def test_a_measured_channel_that_never_changes_is_refused_by_name(dead, value, seed):
    """A sensor not logged or stuck reads one value throughout: the audit refuses the record and
    names the channel(s) instead of failing on singular equations later."""
    s = np.random.default_rng(seed).normal(size=(300, 5))
    for k in dead:
        s[:, k] = value
    with pytest.raises(ValueError, match="in every sample: a sensor that is not logged") as err:
        require_live_channels(s)
    named = {k for k, name in enumerate(CHANNELS) if f"{name} is " in str(err.value)}
    assert named == dead, str(err.value)
    s[:, list(dead)] = np.random.default_rng(seed + 1).normal(size=(300, len(dead)))
    require_live_channels(s)


@pytest.mark.parametrize("profile", ["paper-var", "steps", "multisine"])
def test_a_clean_record_with_x1_in_half_millimetre_steps_is_not_named_an_effect(profile):
    """x1 written in 0.5 mm steps holds still between them: its 4th differences are mostly 0 and
    it read as a noise-free sensor, so the rounding's residual was named a load offset (paper-var,
    confident) or Stribeck friction; its noise is at least its rounding's (step / sqrt(12))."""
    s0, cfg = _rec(profile, duration=20.0)
    s = np.array(s0)
    s[:, 1] = np.round(s[:, 1] / 5e-4) * 5e-4
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == "none" and res.causes == (), (res.cause, res.note)


@pytest.mark.parametrize("channel", [2, 4])
def test_a_lone_pressure_or_spool_glitch_is_mended_before_the_audit_not_named_an_effect(channel):
    """A one-sample spike of x3 or x5 ten times the channel's 99th-percentile step, below the
    refusal's 50: fitted as it stands, it reads as entrained air (or a supply sag); the live
    monitor's outlier gate replaces it by its neighbours' mean first, and the result counts it."""
    s0, cfg = _rec(duration=20.0)
    s = np.array(s0)
    s[700, channel] += 10 * np.quantile(np.abs(np.diff(s0[:, channel])), 0.99)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == "none", (res.cause, res.note)
    assert res.glitches == {ch: int(k == channel) for k, ch in enumerate(CHANNELS) if k}, res.glitches


@pytest.mark.parametrize("n", [1, 10, 249])
def test_a_record_too_short_says_so_before_anything_about_what_it_holds(n):
    """A few samples of a rig at rest are too short first, not held at one command or dead."""
    with pytest.raises(ValueError, match=f"^need at least 250 samples, got {n}$"):
        audit(np.ones((n, 5)))


def _scaled(s, columns, factor):
    out = np.array(s)
    out[:, columns] *= factor
    return out


@pytest.mark.parametrize("kind", ["clean", "rig"])
@pytest.mark.parametrize("columns, factor, said", [
    ([1], 100.0, r"^x1 reaches [\d.]+ m, \d+ times its sensor's span x1_span = 0.1 m: is x1 in mm"),  # cm
    ([1], 1000.0, r"^x1 reaches"),  # mm
    ([4], 100.0, r"^x5 reaches [\d.]+ m, \d+ times its sensor's span x5_span = 0.001 m"),  # 0.01 mm
    ([4], 1000.0, r"^x5 reaches"),
    ([2, 3], 1e-5, r"^the pressures x3 and x4 never exceed [\d.]+ Pa, .* are they in bar, MPa or psi\?"),
    ([2, 3], 1e-6, r"^the pressures x3 and x4 never exceed"),  # MPa
    ([2, 3], 1 / 6894.76, r"^the pressures x3 and x4 never exceed"),  # psi
    ([3], 1e-3, r"^x4 never exceeds [\d.]+ kPa, .* is it in bar"),  # one sensor in kPa
    ([2, 3], 20.0, r"^the pressures reach [\d.]+ MPa, \d+ times the pressure sensors' span p_span"),
    ([2], -1.0, r"^x3 falls to -[\d.]+ MPa, far below vacuum"),
])
def test_a_channel_in_other_units_than_si_is_refused_naming_it(kind, columns, factor, said):
    """Pressures in bar read as a rig that does not obey the model, a spool in 0.01 mm as a healthy
    valve of a hundred times the gain: the record is refused before anything is fitted, naming the
    channel, its reading and the config constant it was held against; unmutated, it is taken."""
    s, cfg = _rec(kind=kind, seed=7)
    _require(s, cfg)
    with pytest.raises(ValueError, match=said):
        _require(_scaled(s, columns, factor), cfg)
    with pytest.raises(ValueError, match=said.replace("^", "")):
        audit(_scaled(s, columns, factor), cfg)


@settings(max_examples=30, deadline=None)
@given(channel=st.sampled_from([1, 4]), ratio=st.floats(0.2, 1e4))
def test_a_reading_is_refused_above_range_times_its_span_and_taken_below(channel, ratio):
    """A rig whose spool travels 3 mm against the default 1 mm span (one of the sweep's rigs of its own)
    is taken: only a reading beyond RANGE times its sensor's span is read as a unit slip."""
    s, cfg = _rec(seed=7)
    key = {1: "x1_span", 4: "x5_span"}[channel]
    peak = float(np.max(np.abs(s[:, channel])))
    own = cfg.model_copy(update={key: peak / ratio})
    if ratio < RANGE * 0.999:
        _require(s, own)
    elif ratio > RANGE * 1.001:
        with pytest.raises(ValueError, match=f"^{CHANNELS[channel]} reaches .* {key} = "):
            _require(s, own)
