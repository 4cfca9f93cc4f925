"""The force balance with observed pressures (monitor.force_observer): its filter identity, its
read-out against numpy, and B + f_v against its 1 % target under noise."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hydromon.contract import RigConfig
from monitor.force_observer import (
    FREE,
    N_OBS_PARAMS,
    N_PRIOR,
    PSI_NOM,
    REPORTED,
    chamber_prior,
    obs_bank_init,
    obs_bank_step,
    obs_matrices,
    solve_with_prior,
)
from monitor.ident_options import IdentOptions
from monitor.layout import N_OBS, O_NE_A, O_NE_B, O_NE_YY, OBS_ORDER, OBS_STATE, STATE_SIZE
from monitor.pipeline import Fleet
from monitor.svf import svf_bank_init, svf_bank_step, svf_matrices
from plant_sim.noise import noise_model
from plant_sim.params import PlantParams
from plant_sim.profiles import PaperIdentification
from plant_sim.simulate import simulate_fleet

H = 0.01


@settings(max_examples=25, deadline=None)
@given(st.floats(20.0, 150.0), st.floats(0.5, 10.0), st.integers(0, 2**32 - 1), st.floats(1e-6, 1e7))
def test_observer_filter_splits_the_svf_exactly(a, wc, seed, scale):
    # F = w_c H + s H: the target w_c H[Fm] and the model part s H[Fm] add up to the plain force
    # balance's F[Fm] for any signal, started at rest alike (the row's identity rests on it)
    rng = np.random.default_rng(seed)
    n = 400
    u = scale * np.cumsum(rng.normal(size=n)) * 0.1 + scale
    mf, mo = svf_matrices(a, H), obs_matrices(a, wc, H)
    sf = np.zeros(6)
    so = np.zeros(N_OBS * OBS_STATE)
    yf, yo = np.zeros((1, 3)), np.zeros((N_OBS, OBS_ORDER))
    uo = np.zeros(N_OBS)
    for k in range(n):
        uo[:] = u[k]
        if k == 0:
            svf_bank_init(sf, 0, u[:1])
            obs_bank_init(so, 0, uo, wc)
        svf_bank_step(mf, sf, 0, u[k:k + 1], yf)
        obs_bank_step(mo, so, 0, uo, yo, False)
        np.testing.assert_allclose(wc * yo[0, 0] + yo[0, 1], yf[0, 0], rtol=1e-9, atol=1e-9 * scale)


def test_observer_filter_refuses_bad_settings():
    for a, wc, h in ((0.0, 2.0, H), (80.0, -1.0, H), (80.0, 2.0, math.inf)):
        with pytest.raises(ValueError):
            obs_matrices(a, wc, h)


def _random_spd(rng, n, scale=1.0):
    q = rng.normal(size=(n, n))
    return (q @ q.T + n * np.eye(n)) * scale


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_solve_with_prior_equals_numpy(seed):
    rng = np.random.default_rng(seed)
    n = N_OBS_PARAMS
    x = rng.normal(size=(300, n))
    y = x @ rng.normal(size=n) + rng.normal(size=300)
    A, b, yy = x.T @ x, x.T @ y, y @ y
    stt = np.zeros(STATE_SIZE)
    stt[O_NE_A:O_NE_A + n * (n + 1) // 2] = A[np.triu_indices(n)]  # packed by rows, as the kernel keeps it
    stt[O_NE_B:O_NE_B + n], stt[O_NE_YY] = b, yy
    S = np.zeros((n, n))
    cols = [0, 1, 3, 7]
    S[np.ix_(cols, cols)] = _random_spd(rng, 4, 0.5)
    mu, c = rng.normal(size=N_PRIOR), _random_spd(rng, N_PRIOR, 0.01)
    kappa, w = 3.0, 300.0
    th, var = np.empty(n), np.empty(4)
    assert solve_with_prior(stt, S, w, kappa, mu, c, th, var)
    # reference: the fit with psi at mu gives f; then the posterior and its sandwich covariance
    free = list(FREE)
    pri = list(range(4, 4 + N_PRIOR))
    tf = np.linalg.solve((A - S)[np.ix_(free, free)], b[free] - (A - S)[np.ix_(free, pri)] @ mu)
    fix = np.zeros(n)
    fix[free], fix[pri] = tf, mu
    f = (yy - 2 * fix @ b + fix @ A @ fix) / (w - len(free)) * kappa
    lam = np.zeros((n, n))
    lam[np.ix_(pri, pri)] = np.linalg.inv(c)
    M = (A - S) / f + lam
    ref = np.linalg.solve(M, b / f + lam @ np.r_[np.zeros(4), mu, np.zeros(n - 4 - N_PRIOR)])
    cov = np.linalg.inv(M) @ (A / f + lam) @ np.linalg.inv(M)
    np.testing.assert_allclose(th, ref, rtol=1e-8, atol=1e-10 * np.abs(ref).max())
    for k in REPORTED:
        assert var[k] == pytest.approx(cov[k, k], rel=1e-8)


def test_solve_with_prior_refuses_a_singular_system():
    stt = np.zeros(STATE_SIZE)  # no rows: every system singular
    th, var = np.empty(N_OBS_PARAMS), np.empty(4)
    assert not solve_with_prior(stt, np.zeros((N_OBS_PARAMS, N_OBS_PARAMS)), 100.0, 1.0, np.ones(N_PRIOR),
                                np.eye(N_PRIOR), th, var)


def test_chamber_prior_is_the_delta_method():
    cp = np.array([1 / 7e8, 6.07e-4, 3e-11, 1e-12])
    cov = np.diag((cp * np.array([2e-3, 1e-3, 5e-3, 0.1])) ** 2)
    mu, c = np.empty(4), np.empty((4, 4))
    assert chamber_prior(cp, cov, mu, c)
    psi = lambda p: np.array([p[1] / p[0], p[2] / p[0], p[3] / p[0], 1 / p[0]]) / PSI_NOM  # noqa: E731
    np.testing.assert_allclose(mu, psi(cp), rtol=1e-12)
    J = np.empty((4, 4))
    for j in range(4):
        d = np.zeros(4)
        d[j] = cp[j] * 1e-6
        J[:, j] = (psi(cp + d) - psi(cp - d)) / (2 * d[j])
    np.testing.assert_allclose(c, J @ cov @ J.T, rtol=1e-6)
    assert not chamber_prior(np.array([-1e-9, 6e-4, 3e-11, 0.0]), cov, mu, c)


def _b_fv(noise: str, seeds: list[int], observer: bool = True, gap: bool = False):
    runs = simulate_fleet(RigConfig(), [PlantParams()] * len(seeds), [PaperIdentification()] * len(seeds), 10.0,
                          noise=noise_model(noise), seeds=seeds)
    fleet = Fleet(IdentOptions(pressure_observer=observer), capacity=len(seeds))
    for i in range(len(seeds)):
        fleet.add_rig(f"r{i}")
    for i, run in enumerate(runs):
        s = run.samples
        if gap:  # 0.2 s lost at 5 s: the filters restart (as the monitor does on a seq gap)
            fleet.update(np.full(500, i), s[:500])
            fleet.reset_signals(i)
            s = s[520:]
        fleet.update(np.full(len(s), i), s)
    true = PlantParams().B + PlantParams().f_v
    est = np.array([fleet.estimate(i).params["B_fv"] for i in range(len(seeds))])
    se = np.array([fleet.estimate(i).std_errors["B_fv"] for i in range(len(seeds))])
    return (est - true) / true, np.abs(est - true) / se


def test_b_fv_meets_the_issue_target_at_realistic_noise():
    """Paper's input, 10 s, realistic noise, seeds 0-9 (docs/noise.md's table): B + f_v within
    1 % mean absolute error (the target; measured 0.93 %, the plain force balance 4.38 %),
    the truth inside +-3 SE in at least 9 of 10."""
    rel, z = _b_fv("realistic", list(range(10)))
    assert np.mean(np.abs(rel)) < 0.01, np.mean(np.abs(rel))
    assert np.sum(z <= 3) >= 9, z
    plain, _ = _b_fv("realistic", list(range(10)), observer=False)
    assert np.mean(np.abs(plain)) > 3 * np.mean(np.abs(rel))  # the observer is what does it


def test_b_fv_standard_errors_stay_honest_at_stress_noise():
    rel, z = _b_fv("stress", list(range(10)))
    assert np.sum(z <= 3) >= 9, z


def test_b_fv_survives_a_gap():
    # a gap restarts the filters: the observer's start transient gets an amplitude of its own
    rel, z = _b_fv("realistic", list(range(10)), gap=True)
    assert np.mean(np.abs(rel)) < 0.015, np.mean(np.abs(rel))
    assert np.sum(z <= 3) >= 9, z
    clean, _ = _b_fv("none", [0], gap=True)
    assert abs(clean[0]) < 2e-4, clean


def test_observer_rows_wait_after_a_step_in_the_command():
    # on `--profile steps` (healthy rig, realistic noise, 20 s) the force balance on observed
    # pressures, taking its rows right after each step in ug, put B + f_v 9.1 % high at 6.7 SE on
    # seed 3 without the constant force F_0 and graded the rig `fault` (picked for its smaller SE).
    # With F_0 the unguarded rows are off by at most 2.7 SE over seeds 0-9, and the guard halves
    # the worst (1.2 SE)
    from monitor.ident_options import IdentOptions
    from monitor.pipeline import Pipeline
    from plant_sim.noise import noise_model
    from plant_sim.profiles import parse_profile
    from plant_sim.simulate import simulate

    true = 6025.0
    z_guarded, z_unguarded = [], []
    for seed in range(10):
        run = simulate(parse_profile("steps"), 20.0, noise=noise_model("realistic"), seed=seed)
        guarded = Pipeline().run(run.samples)[1]
        assert guarded.grade == "health", seed
        z_guarded.append(abs(guarded.params["B_fv"] - true) / guarded.std_errors["B_fv"])
        unguarded = Pipeline(options=IdentOptions(observer_step_guard=0.0)).run(run.samples)[1]
        z_unguarded.append(abs(unguarded.params["B_fv"] - true) / unguarded.std_errors["B_fv"])
    assert max(z_guarded) <= 3.0, z_guarded
    assert max(z_unguarded) > 1.5 * max(z_guarded), (z_guarded, z_unguarded)  # the guard matters
