"""monitor core: RLS vs batch least squares, SVF vs scipy, identification accuracy, fleet == single."""

import pickle

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from hydromon.contract import PARAM_NAMES, RigConfig
from monitor.layout import SVF_STATE
from monitor.pipeline import Fleet, Pipeline
from monitor.rls import RLS, rls_step
from monitor.svf import svf_bank_init, svf_bank_step, svf_init, svf_matrices, svf_step
from plant_sim.degradation import TABLE4_PAPER_GRADES, table4_group
from plant_sim.noise import noise_model
from plant_sim.profiles import PaperIdentification, PaperVariable
from plant_sim.simulate import simulate, simulate_fleet


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 6))
def test_rls_equals_batch_least_squares(seed, n):
    rng = np.random.default_rng(seed)
    theta = rng.normal(size=n) * 10 ** rng.uniform(-2, 2, size=n)
    X = rng.normal(size=(20 * n + 10, n))
    y = X @ theta
    r = RLS(n, p0=1e10, p_max=1e12 * n)
    for row, yy in zip(X, y):
        est = r.update(row, yy)
    ls = np.linalg.lstsq(X, y, rcond=None)[0]
    assert np.allclose(est, ls, rtol=1e-6, atol=1e-6 * np.abs(theta).max())
    assert np.allclose(est, theta, rtol=1e-6, atol=1e-6 * np.abs(theta).max())


def test_rls_no_windup_without_excitation():
    th, P = np.zeros(4), np.eye(4)
    phi = np.array([1.0, 0.5, -0.2, 2.0])
    for _ in range(200):
        rls_step(th, P, phi * np.random.default_rng(1).normal(), 1.0, 0.99, 1e6)
    for _ in range(100_000):
        rls_step(th, P, np.zeros(4), 0.0, 0.99, 1e6)
    assert np.all(np.isfinite(th)) and np.all(np.isfinite(P))
    assert np.trace(P) <= 1e6 and np.allclose(P, P.T)


def test_rls_refuses_nonfinite_rows():
    r = RLS(2)
    with pytest.raises(ValueError):
        r.update([np.nan, 1.0], 1.0)
    th, P = np.zeros(2), np.eye(2)
    assert np.isnan(rls_step(th, P, np.array([np.inf, 1.0]), 1.0, 1.0, 1e9))
    assert np.all(th == 0) and np.all(P == np.eye(2))


def test_svf_at_rest_stays_at_rest_and_refuses_bad_bandwidths():
    for a, h in ((25.0, 0.01), (80.0, 0.01), (300.0, 0.002)):
        m = svf_matrices(a, h)
        x, y = np.zeros(SVF_STATE), np.zeros(3)
        svf_init(m, x, 3.5e6)
        for _ in range(50):
            svf_step(m, x, 3.5e6, y)
        np.testing.assert_allclose(y, [3.5e6, 0.0, 0.0], atol=1e-6 * 3.5e6)
    with pytest.raises(ValueError):
        svf_matrices(-1.0, 0.01)


@settings(max_examples=30, deadline=None)
@given(a=st.floats(5.0, 300.0), n=st.integers(1, 12), seed=st.integers(0, 2**31 - 1))
def test_svf_bank_is_svf_step_signal_by_signal(a, n, seed):
    """The kernels' fused bank step is bit for bit the reference step on each signal."""
    rng = np.random.default_rng(seed)
    m = svf_matrices(a, 0.01)
    u = rng.normal(size=(40, n)) * 10.0 ** rng.uniform(-6, 7, size=n)
    base = 3
    bank = np.zeros(base + n * SVF_STATE)
    svf_bank_init(bank, base, u[0])
    refs = [np.zeros(SVF_STATE) for _ in range(n)]
    for x, u0 in zip(refs, u[0]):
        svf_init(m, x, u0)
    yb, yr = np.zeros((n, 3)), np.zeros(3)
    for row in u[1:]:
        svf_bank_step(m, bank, base, row, yb)
        for i, x in enumerate(refs):
            svf_step(m, x, row[i], yr)
            assert np.array_equal(yb[i], yr)
            assert np.array_equal(bank[base + SVF_STATE * i:base + SVF_STATE * (i + 1)], x)


def _catmull_rom(p0, p1, p2, p3, tau):
    return 0.5 * (2 * p1 + (p2 - p0) * tau + (2 * p0 - 5 * p1 + 4 * p2 - p3) * tau**2
                  + (3 * p1 - p0 - 3 * p2 + p3) * tau**3)


@settings(max_examples=20, deadline=None)
@given(a=st.floats(5.0, 150.0), seed=st.integers(0, 2**32 - 1), scale=st.floats(1e-6, 1e7))
def test_svf_outputs_are_the_filter_states_for_the_cubic_through_the_samples(a, seed, scale):
    # the hold's promise: with the input taken as the Catmull-Rom cubic through the samples,
    # the outputs are the continuous filter's states [F u, sF u, s^2F u] one sample back
    # (checked against a fine RK4 integration of the continuous filter; the first-order hold
    # it replaces was off by O((a h)^2) here)
    h, n, sub = 0.01, 40, 200
    u = np.concatenate([[0.0, 0.0, 0.0], np.random.default_rng(seed).normal(size=n) * scale])
    m = svf_matrices(a, h)
    x, y = np.zeros(SVF_STATE), np.zeros(3)
    svf_init(m, x, 0.0)  # at rest on the padding: x at the instant of u[1], history u[0..2]
    A = np.array([[0, 1, 0], [0, 0, 1], [-a**3, -3 * a**2, -3 * a]])
    b = np.array([0, 0, a**3])
    xc = np.zeros(3)
    dt = h / sub
    for j in range(n):
        svf_step(m, x, u[j + 3], y)  # -> the state at the instant of u[j + 2]
        p = u[j:j + 4]
        f = lambda s, z: A @ z + b * _catmull_rom(*p, s / h)  # noqa: E731
        for i in range(sub):
            s0 = i * dt
            k1 = f(s0, xc)
            k2 = f(s0 + dt / 2, xc + dt / 2 * k1)
            k3 = f(s0 + dt / 2, xc + dt / 2 * k2)
            k4 = f(s0 + dt, xc + dt * k3)
            xc = xc + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        assert np.allclose(y, xc, rtol=1e-6, atol=1e-9 * scale * np.array([1, a, a * a]))


@pytest.fixture(scope="module")
def table2_run():
    run = simulate(PaperIdentification(), 10.0)
    _, a = Pipeline().run(run.samples)
    return run, a


# Noise-free relative errors of the current recipe (paper's input, 10 s), measured 2026-11-23, and
# the regression bound of each: about 10x the measured error, so a change that makes any estimate
# worse by an order of magnitude fails here long before it reaches the 0.5 % target (docs/noise.md).
NOISE_FREE_BOUNDS = {  # name: (measured, bound)
    # K_t shares x1's mean with the constant force F_0 (4.0e-7; -4.4e-9 without F_0)
    "m": (2.0e-4, 1.5e-3), "B_fv": (2.8e-5, 2e-4), "f_c": (-8.4e-4, 5e-3), "K_t": (4.0e-7, 4e-6),
    "inv_beta_e": (1.4e-5, 2e-4), "CdW_sqrt_rho": (-8.0e-6, 1e-4), "C_ip": (-9.5e-6, 1e-4),
    "two_zeta_omega": (1.1e-4, 1.5e-3), "omega_sv2": (2.0e-4, 2e-3), "K_sv_omega_sv2": (2.0e-4, 2e-3),
    "K_sv": (1.0e-6, 2e-5),
}


def test_table2_noise_free(table2_run):
    """Paper's identification input, 10 s, noise-free: the target (within 0.5 %, f_c within
    1 %; |C_ep| < 1e-13), and each estimate within its regression bound (NOISE_FREE_BOUNDS)."""
    run, a = table2_run
    true = run.params.identified()
    for name in PARAM_NAMES:
        if name in ("f_c", "C_ep"):
            continue
        assert a.params[name] == pytest.approx(true[name], rel=5e-3), name
    assert abs(a.params["C_ep"]) < 1e-13
    assert a.params["f_c"] == pytest.approx(true["f_c"], rel=0.01)
    for name, (_, bound) in NOISE_FREE_BOUNDS.items():
        assert abs(a.params[name] / true[name] - 1) < bound, (name, a.params[name] / true[name] - 1)
    assert abs(a.params["C_ep"]) < 1e-17  # measured -3.1e-19 (true 0)
    assert set(NOISE_FREE_BOUNDS) | {"C_ep"} == set(PARAM_NAMES)


def test_standard_errors_cover_truth_at_realistic_noise():
    """Honest standard errors: the truth inside +-3 SE (SEs not too small), and the errors'
    spread in SEs near 1 (SEs not too large: measured rms 1.00 over these 24; an SE inflated
    2.5x would give 0.4)."""
    runs = simulate_fleet(RigConfig(), [table4_group(2)] * 4, [PaperIdentification()] * 4, 10.0,
                          noise=noise_model("realistic"), seeds=[11, 12, 13, 14])
    z = []
    for run in runs:
        _, a = Pipeline().run(run.samples)
        true = run.params.identified()
        for k in ("inv_beta_e", "CdW_sqrt_rho", "C_ip", "K_sv_omega_sv2", "omega_sv2", "B_fv"):
            z.append((a.params[k] - true[k]) / a.std_errors[k])
        for k in ("inv_beta_e", "CdW_sqrt_rho", "C_ip"):
            assert a.params[k] == pytest.approx(true[k], rel=0.01), k
        assert a.params["K_sv_omega_sv2"] == pytest.approx(true["K_sv_omega_sv2"], rel=0.02)
    z = np.abs(np.array(z))
    assert np.sum(z <= 3) >= 0.9 * len(z)
    assert np.sqrt(np.mean(z ** 2)) > 0.4, f"errors are only {np.sqrt(np.mean(z ** 2)):.2f} SE rms: SEs inflated"


@pytest.mark.parametrize("noise", ["none", "realistic", "stress"])
def test_table4_groups_graded_as_the_paper(noise):
    """Paper's variable-condition input, 10 s; 10 noise seeds per group at both noise models."""
    n_seeds = 1 if noise == "none" else 10
    groups = [g for g in (1, 2, 3, 4, 5) for _ in range(n_seeds)]
    seeds = [100 + k for _ in (1, 2, 3, 4, 5) for k in range(n_seeds)]
    runs = simulate_fleet(RigConfig(), [table4_group(g) for g in groups], [PaperVariable()] * len(groups), 10.0,
                          noise=noise_model(noise), seeds=seeds)
    fleet = Fleet(capacity=len(groups))
    for i in range(len(groups)):
        fleet.add_rig(f"r{i}")
    for i, run in enumerate(runs):
        fleet.update(np.full(len(run.samples), i), run.samples)
    wrong = [(g, seed, fleet.estimate(i).grade) for i, (g, seed) in enumerate(zip(groups, seeds))
             if fleet.estimate(i).grade != TABLE4_PAPER_GRADES[g]]
    assert not wrong, wrong


@pytest.mark.parametrize("threads", [1, 3])
def test_fleet_equals_single_rig_path(threads):
    runs = simulate_fleet(RigConfig(), [table4_group(g) for g in (1, 4, 5)], [PaperVariable()] * 3, 6.0,
                          noise=noise_model("realistic"), seeds=[1, 2, 3])
    singles = []
    for run in runs:
        ev, a = Pipeline().run(run.samples)
        singles.append((ev, a))
    fleet = Fleet(threads=threads)  # batches of >= Fleet.PARALLEL_MIN samples split rigs over threads
    for i in range(3):
        fleet.add_rig(f"r{i}")
    n = len(runs[0].samples)
    # interleave rigs sample by sample, in uneven batches
    rig = np.tile(np.arange(3), n)
    samples = np.stack([r.samples for r in runs], axis=1).reshape(-1, 5)
    cuts = [0, 7, 500, 1234, len(rig)]
    events = [fleet.update(rig[a:b], samples[a:b]) for a, b in zip(cuts, cuts[1:])]
    for i in range(3):
        fa = fleet.estimate(i)
        sa = singles[i][1]
        for k in PARAM_NAMES:
            assert fa.params[k] == pytest.approx(sa.params[k], rel=1e-9, abs=1e-300), k
        assert fa.level == sa.level
        levels = np.concatenate([e.level[e.rig == i] for e in events])
        assert np.array_equal(levels, singles[i][0].level)
    # events come in arrival order whatever the threads
    for e, (a, b) in zip(events, zip(cuts, cuts[1:])):
        assert np.all(np.diff(e.sample) > 0) and np.all(e.rig == rig[a:b][e.sample])


def test_state_pickles_and_resumes():
    run = simulate(PaperIdentification(), 4.0, noise=noise_model("realistic"), seed=5)
    a = Pipeline()
    a.run(run.samples[:200])
    b = pickle.loads(pickle.dumps(a))
    _, ra = a.run(run.samples[200:])
    _, rb = b.run(run.samples[200:])
    assert ra.params == rb.params


def test_pipeline_rejects_bad_samples():
    p = Pipeline()
    with pytest.raises(ValueError, match="non-finite"):
        p.update([2.0, np.nan, 1e6, 1e6, 0.0])
    with pytest.raises(ValueError, match="N, 5"):
        p.run(np.zeros((3, 4)))


def test_staggered_fleet_evaluates_each_rig_at_its_own_phase():
    from monitor.evaluations import eval_phase

    ids = [f"rig-{i:04d}" for i in range(40)]
    fleet = Fleet(stagger=True)
    for rid in ids:
        fleet.add_rig(rid)
    run = simulate(PaperIdentification(), 0.5, noise=noise_model("realistic"), seed=3)
    rig = np.tile(np.arange(len(ids)), len(run.samples))
    ev = fleet.update(rig, np.repeat(run.samples, len(ids), axis=0))
    phases = np.array([eval_phase(r, 10) for r in ids])
    assert len(set(phases.tolist())) >= 8  # the ids spread over the window
    assert np.all((ev.counts + phases[ev.rig]) % 10 == 0)
    # every rig reported after each of its windows, and no tick carries them all
    assert len(ev) == sum(len([n for n in range(1, 51) if (n + p) % 10 == 0]) for p in phases)
    per_tick = np.bincount(ev.sample // len(ids))
    assert per_tick.max() < len(ids) / 2


@settings(max_examples=60, deadline=None)
@given(st.floats(20.0, 400.0), st.floats(0.1, 3.0), st.floats(0.5, 5.0), st.floats(-0.5, 0.5))
@example(316.0, 0.125, 1.0, 0.0)
def test_valve_jacobian_equals_central_differences(omega, zeta, gain, skew):
    """The valve read-out's analytic Jacobian (monitor.estimates._valve_jacobian) against central
    differences of valve_physical, for under- and overdamped valves (complex and real poles)."""
    from monitor.estimates import _valve_jacobian, valve_physical

    h = 0.01
    poles = np.roots([1.0, 2 * zeta * omega, omega ** 2])
    if abs(poles[0] - poles[1]) < 1e-3 * omega:
        return  # repeated poles: neither is defined
    z = np.exp(poles * h)
    if np.abs(z).min() < 0.02:
        return  # a pole far beyond the 100 Hz sampling: a2 ~ 0, central differences lose it
    if np.abs(np.angle(z)).max() > 0.9 * np.pi:
        # omega_d h near pi (omega ~ 316 rad/s here): the valve is at the sampling's Nyquist
        # frequency, its poles near the complex log's branch cut, where central differences
        # straddle a kink (found: omega 316, zeta 0.125, 3e-4 apart); such a valve is aliased
        return
    a1, a2 = float(np.real(-(z[0] + z[1]))), float(np.real(z[0] * z[1]))
    b = gain * (1 + a1 + a2) / 3.0
    th = np.array([a1, a2, b * (1 + skew), b, b * (1 - skew)])
    phys = valve_physical(th, h)
    J = np.zeros((3, 5))
    _valve_jacobian(th, h, phys, J)
    fd = np.zeros((3, 5))
    for j in range(5):
        d = 1e-6 * max(abs(th[j]), 1e-3)
        up, dn = th.copy(), th.copy()
        up[j] += d
        dn[j] -= d
        fd[:, j] = (valve_physical(up, h) - valve_physical(dn, h)) / (2 * d)
    for i in range(3):
        np.testing.assert_allclose(J[i], fd[i], rtol=1e-5, atol=1e-6 * np.abs(fd[i]).max(), err_msg=str(i))


@pytest.mark.parametrize("noise, bound", [("realistic", 2e-4), ("stress", 5e-4)])
def test_static_gain_is_honest_under_noise(noise, bound):
    """The valve's static gain K_sv (graded by default): paper's input, 10 s, seeds 0-9, mean error
    within bound and the truth inside +-3 SE in at least 9 of 10 seeds. Measured 0.012 % (10/10)
    and 0.027 % (10/10); the ARX's DC gain it replaced gave 0.06 % at stress with 6/10."""
    from plant_sim.params import PlantParams

    runs = simulate_fleet(RigConfig(), [PlantParams()] * 10, [PaperIdentification()] * 10, 10.0,
                          noise=noise_model(noise), seeds=list(range(10)))
    fleet = Fleet(capacity=10)
    for i in range(10):
        fleet.add_rig(f"r{i}")
    for i, run in enumerate(runs):
        fleet.update(np.full(len(run.samples), i), run.samples)
    true = PlantParams().K_sv
    est = np.array([fleet.estimate(i).params["K_sv"] for i in range(10)])
    se = np.array([fleet.estimate(i).std_errors["K_sv"] for i in range(10)])
    assert np.mean(np.abs(est / true - 1)) < bound
    assert np.sum(np.abs(est - true) <= 3 * se) >= 9, (est / true - 1, se / true)
