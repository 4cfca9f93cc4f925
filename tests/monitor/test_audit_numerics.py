"""Numerics of the audit's pieces: orifice factors, the sagged supply flow, the valve filter
and the free run, against the plant and scipy (hypothesis properties where they are numerics)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import cont2discrete, lfilter, savgol_filter

from monitor.audit.candidates import _sagged_factor
from monitor.audit.freerun import channel_scores, free_run
from monitor.audit.eiv import COMPENSATION_MAX, compensated_lstsq, noise_share
from monitor.audit.residuals import Block, orifice_factors, rest_allowance, valve_response
from monitor.audit.signals import _savgol, noise_at
from monitor.audit.valve_fit import _filter2, _valve_filter
from plant_sim.degradation import degrade
from plant_sim.model import orifice_z
from plant_sim.params import Effects
from plant_sim.profiles import parse_profile
from plant_sim.simulate import simulate

finite = st.floats(-1e7, 2e7, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(xv=st.floats(-1e-3, 1e-3, allow_nan=False), p1=finite, p2=finite)
def test_orifice_factors_match_the_plant(xv, p1, p2):
    z1, z2 = orifice_factors(np.array([xv]), np.array([p1]), np.array([p2]), 12e6)
    assert (z1[0], z2[0]) == pytest.approx(orifice_z(xv, p1, p2, 12e6), rel=1e-12, abs=1e-9)


def test_a_leakage_estimated_below_zero_is_simulated_as_none_not_as_the_fallbacks():
    """A mass estimated <= 0 takes the fallback's (the nominal model's) mass, but a leakage a
    little below zero is no leakage: the fallback's C_ep, raised by the effect an extension
    explains, drained the chambers of a right pair's free run."""
    from monitor.audit.freerun import plant_from_params

    true = degrade(0.3).identified()
    fallback = {**true, "C_ip": 5e-11, "C_ep": 3e-14, "m": 90.0}
    plant, clamped = plant_from_params({**true, "C_ip": -1e-13, "C_ep": -2e-15, "m": -5.0}, fallback)
    assert plant.C_ip == 0.0 and plant.C_ep == 0.0 and plant.m == 90.0
    assert {"C_ip", "C_ep", "m"} <= set(clamped)
    plant, clamped = plant_from_params({**true, "C_ep": 1e-15}, fallback)
    assert plant.C_ep == 1e-15 and plant.C_ip == true["C_ip"] and clamped == []


@settings(max_examples=40, deadline=None)
@given(a=st.floats(1e-9, 1e-6), dp=st.floats(0.0, 2e7), r=st.floats(0.0, 5e10))
def test_sagged_flow_solves_its_equation(a, dp, r):
    q = _sagged_factor(np.array([a]), np.array([dp]), r)[0]
    assert q >= 0
    assert q == pytest.approx(a * np.sqrt(2.0 * max(dp - r * q, 0.0)), rel=1e-6, abs=1e-15)


@settings(max_examples=20, deadline=None)
@given(omega=st.floats(20.0, 600.0), zeta=st.floats(0.15, 2.0), level=st.floats(-3.0, 3.0))
def test_valve_response_has_unit_dc_gain(omega, zeta, level):
    y = valve_response(omega, zeta, 0.01, np.full(3000, level))
    assert y[-1] == pytest.approx(level, rel=1e-6, abs=1e-9)


def test_valve_response_matches_the_plant_valve():
    """The FOH valve model driven by the recorded du reproduces the simulated spool."""
    run = simulate(parse_profile("chirp"), 10.0, params=degrade(0.3))
    c = run.config
    du = c.K_p * (run.ug - c.K_f * run.states[:, 0])
    p = run.params
    y = p.K_sv * valve_response(p.omega_sv, p.zeta_sv, c.h, du)
    x5 = run.states[:, 4]
    assert np.max(np.abs(y - x5)[50:]) < 0.01 * np.max(np.abs(x5))


def test_free_run_with_true_parameters_reproduces_the_record():
    """The parameter mapping (B = B_fv with f_v = 0, theta -> W, ...) is exact; a smooth
    command keeps the free run's linear interpolation of the sampled ug out of the comparison."""
    run = simulate(parse_profile("paper-id"), 10.0, params=degrade(0.5),
                   effects=Effects(load_offset=500.0, dead_band=2e-5))
    fr = free_run(run.samples, run.config, run.params.identified(), Effects(load_offset=500.0, dead_band=2e-5))
    scores = channel_scores(run.measured, fr.measured, slice(0, len(run.t)))
    assert not fr.diverged and fr.clamped == ()
    assert all(s["nrmse"] < 2e-3 for s in scores.values()), scores


@settings(max_examples=40, deadline=None)
@given(omega=st.floats(5.0, 2500.0), zeta=st.floats(0.05, 3.0), h=st.floats(1e-3, 2e-2))
def test_valve_filter_is_scipys_first_order_hold(omega, zeta, h):
    b, a, _ = cont2discrete(([omega * omega], [1.0, 2.0 * zeta * omega, omega * omega]), h, method="foh")
    b2, a2 = _valve_filter.__wrapped__(omega, zeta, h)
    np.testing.assert_allclose(a2, np.ravel(a), rtol=0, atol=1e-9)
    np.testing.assert_allclose(b2, np.ravel(b), rtol=0, atol=1e-9 * np.max(np.abs(b)))


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(31, 400), window=st.sampled_from([11, 31]),
       cols=st.sampled_from([0, 3]))
def test_savgol_and_the_valve_filter_are_scipys(seed, n, window, cols):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, cols) if cols else n).cumsum(axis=0)
    want = savgol_filter(x, window, 3, mode="interp", axis=0)
    np.testing.assert_allclose(_savgol(x, window), want, rtol=0, atol=1e-9 * np.max(np.abs(x)))
    b, a = _valve_filter(float(rng.uniform(20, 600)), float(rng.uniform(0.15, 1.5)), 0.01)
    u = x if x.ndim == 1 else x[:, 0]
    np.testing.assert_allclose(_filter2(b, a, u), lfilter(b, a, u), rtol=0, atol=1e-9 * np.max(np.abs(u)))


def test_a_free_run_holds_a_mass_it_cannot_integrate_at_the_smallest_stable_one():
    """A mass estimated <= 0 (fault-grade health: the piston barely accelerates) falls back to a
    floor; at 1 kg against the paper's 6000 N s/m the viscous pole left RK4's stability region and
    the free run of an otherwise right model diverged."""
    from monitor.audit.freerun import stable_mass
    from plant_sim.integrate import DEFAULT_SUBSTEPS
    from plant_sim.params import PlantParams

    run = simulate(parse_profile("paper-id"), 5.0, params=degrade(0.3))
    cfg = run.config
    true = run.params.identified()
    dt = cfg.h / DEFAULT_SUBSTEPS
    floor = stable_mass(PlantParams(**{**run.params.model_dump(), "m": 1.0}), cfg, dt)
    assert 1.0 < floor < true["m"]
    for m in (1.0, -50.0):
        fr = free_run(run.samples, cfg, {**true, "m": m})
        assert not fr.diverged and "m" in fr.clamped
        assert channel_scores(run.samples[:, 1:], fr.measured, slice(0, None))["x1"]["nrmse"] < 0.05
    assert free_run(run.samples, cfg, true).clamped == ()


@settings(max_examples=40, deadline=None)
@given(a=st.floats(-1.0, 1.0), b=st.floats(-0.1, 0.1), c=st.floats(-0.05, 0.05), h=st.floats(1e-3, 2e-2))
def test_the_sample_to_sample_velocity_is_exact_on_a_parabola_and_follows_a_surge(a, b, c, h):
    """Signals.vs, the Stribeck hump's velocity: the central difference, exact on x1 = c + b t +
    a t^2 away from the ends; a 3-sample velocity surge it follows to its peak within one
    sample's worth of motion, where the lightly smoothed velocity spreads it over 11 samples."""
    from monitor.audit.signals import signals

    n = 300
    t = np.arange(n) * h
    x1 = c + b * t + a * t * t
    s = np.column_stack([np.zeros(n), x1, np.full(n, 1e6), np.full(n, 1e6), np.zeros(n)])
    sig = signals(s, h)
    np.testing.assert_allclose(sig.vs[1:-1], (b + 2.0 * a * t)[1:-1], rtol=0, atol=1e-9 * (abs(b) + abs(a) + 1))
    v = np.full(n, 1e-3)  # [m/s] creep with a surge to 20 mm/s over samples 150-152
    v[150:153] = 0.02
    x1 = np.concatenate([[0.0], np.cumsum(v[:-1] * h)])
    sig = signals(np.column_stack([np.zeros(n), x1, np.full(n, 1e6), np.full(n, 1e6), np.zeros(n)]), h)
    assert sig.vs[151] == pytest.approx(0.02, rel=1e-6)
    assert abs(sig.vl[151] - 0.02) > 0.005


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(30, 300), k=st.integers(1, 5),
       noise=st.floats(0.01, 3.0), scales=st.lists(st.floats(-6, 6), min_size=5, max_size=5))
def test_the_noise_compensation_never_leaves_an_indefinite_normal_matrix(seed, n, k, noise, scales):
    """Errors-in-variables least squares on regressors of any scale whose noise may exceed their
    signal: the compensated normal matrix keeps at least 1 - COMPENSATION_MAX of the data's
    energy in every direction, the estimate is finite, and it is (X'X - c S)^-1 X'y with c = 1
    where the noise holds at most COMPENSATION_MAX (the full compensation)."""
    rng = np.random.default_rng(seed)
    scale = 10.0 ** np.array(scales[:k])
    signal = rng.normal(size=(n, k)) * rng.uniform(0.0, 1.0, size=k)
    load = noise * rng.normal(size=(n, k, 2)) / np.sqrt(2.0)
    X = (signal + load.sum(axis=2) / np.sqrt(2.0)) * scale
    load = load * scale[None, :, None]
    y = X @ rng.normal(size=k) + rng.normal(size=n)
    th = compensated_lstsq(X, y, load)
    assert np.all(np.isfinite(th))
    G, S = X.T @ X, np.einsum("rik,rjk->ij", load, load)
    share = noise_share(G, S)
    used = S if share <= COMPENSATION_MAX else S * COMPENSATION_MAX / share
    assert scipy.linalg.eigh(G - used, G, eigvals_only=True)[0] >= 1.0 - COMPENSATION_MAX - 1e-6
    np.testing.assert_allclose(th, np.linalg.solve(G - used, X.T @ y), rtol=1e-6, atol=1e-9 * np.max(np.abs(th)))


@settings(max_examples=60, deadline=None)
@given(c=st.lists(st.floats(-1e3, 1e3), min_size=4, max_size=4), k=st.floats(-1e3, 1e3),
       start=st.integers(0, 400), n=st.integers(10, 400))
def test_noise_at_reads_no_noise_on_a_cubic_and_scales_with_the_signal(c, k, start, n):
    t = np.arange(1000) * 0.01
    rows = np.arange(start, start + n)
    cubic = c[0] + c[1] * t + c[2] * t ** 2 + c[3] * t ** 3  # a 4th difference of a cubic is 0
    assert noise_at(cubic, rows) <= 1e-9 * (1.0 + np.max(np.abs(cubic)))
    x = np.random.default_rng(int(start)).standard_normal(1000)
    assert noise_at(k * x, rows) == pytest.approx(abs(k) * noise_at(x, rows), rel=1e-9, abs=1e-12)


def test_noise_at_reads_white_noise_where_asked_and_ignores_motion_elsewhere():
    rng = np.random.default_rng(5)
    t = np.arange(4000) * 0.01
    x = np.where(t < 20.0, 0.01 * np.sin(40.0 * t) ** 3, 0.0) + 5e-6 * rng.standard_normal(len(t))
    still = np.arange(2100, 3900)
    assert noise_at(x, still) == pytest.approx(5e-6, rel=0.1)
    assert noise_at(x, np.arange(100, 1900)) > 3 * 5e-6  # where it moves, the motion reads as noise
    assert np.isnan(noise_at(x, np.array([], dtype=int)))


def test_the_rest_rows_allowance_is_the_pressures_margin_plus_what_x1_s_noise_carries():
    load = np.zeros((3, 4, 2))
    load[:, 0, 0], load[:, 1, 1] = 0.01, 2e-4  # acceleration [m/s^2], velocity [m/s] noise rms
    b = Block("rest", np.zeros(3), np.zeros((3, 4)), ("m", "B_fv", "f_c", "K_t"), np.arange(3),
              np.ones(3, bool), margin=10.0, noise_load=load)
    th = {"m": 500.0, "B_fv": 1e4, "f_c": 80.0, "K_t": 0.0}
    np.testing.assert_allclose(rest_allowance(b, th), np.hypot(10.0, 2.0 * np.hypot(5.0, 2.0)))
    np.testing.assert_allclose(rest_allowance(b, {**th, "m": 0.0, "B_fv": 0.0}), 10.0)


@settings(max_examples=40, deadline=None)
@given(step=st.sampled_from([1e-6, 1e-5, 1e-3, 400.0, 1e3]), noise=st.floats(0.0, 0.2), seed=st.integers(0, 999))
def test_a_quantized_channel_s_noise_is_at_least_its_rounding(step, noise, seed):
    """A channel written in whole steps (a quantized sensor, or few decimals) holds still between
    steps, so most 4th differences are 0 and a 1 mm step of x1 read as noise-free; its noise is at
    least step / sqrt(12). Unrounded values have no such step."""
    from monitor.audit.signals import noise_levels, resolution

    rng = np.random.default_rng(seed)
    t = np.arange(2000) * 0.01
    s = np.column_stack([np.sin(t), 30 * step * np.sin(0.7 * t), 4e6 + 1e5 * np.sin(t), 7e6 + 1e5 * np.cos(t),
                         1e-4 * np.sin(1.3 * t)])
    s[:, 1:] += rng.normal(0.0, 1.0, (2000, 4)) * np.array([noise * step, 5e3, 5e3, 5e-7])
    assert resolution(s[:, 1]) == 0.0 and resolution(s[:, 2]) == 0.0
    s[:, 1] = np.round(s[:, 1] / step) * step
    assert resolution(s[:, 1]) == pytest.approx(step, rel=1e-6)
    assert noise_levels(s)[0] >= step / np.sqrt(12.0) * (1 - 1e-9)
