"""Tests for monitor.td: Han's tracking differentiator (paper section 3.2)."""

from __future__ import annotations

import copy
import math
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from monitor.td import TrackingDifferentiator, config_scales, fhan, td_filter, td_lag, td_step, td_step_batch

H, R, H0 = 0.01, 100.0, 0.05  # the paper's sample step [s] and T-D settings
SETTLE = 300  # samples; the linear band's double pole 1 - h/h0 = 0.8 leaves 300 * 0.8^300 < 1e-26

hyp = settings(deadline=None, max_examples=40)


def _han2009(x1, x2, r, h):
    """Han (2009) fhan in its published form (IEEE TIE 56(3)), with the fsg switch functions."""
    def fsg(v, d):
        return (np.sign(v + d) - np.sign(v - d)) / 2.0
    d = r * h * h
    a0 = h * x2
    y = x1 + a0
    a1 = math.sqrt(d * (d + 8.0 * abs(y)))
    a2 = a0 + np.sign(y) * (a1 - d) / 2.0
    a = (a0 + y) * fsg(y, d) + a2 * (1.0 - fsg(y, d))
    return -r * (a / d) * fsg(a, d) - r * np.sign(a) * (1.0 - fsg(a, d))


def _linear_response(h0, h, f):
    """Exact small-signal response of update's outputs: value z c^2/(z-1+c)^2, derivative (z-1)/h times it."""
    c = h / h0
    z = np.exp(2j * math.pi * f * h)
    hv = z * c * c / (z - 1.0 + c) ** 2
    return hv, hv * (z - 1.0) / h


def _magnitude(exp10, mant):
    return mant * 10.0**exp10, 10.0 ** (exp10 + 1)  # amplitude, scale = its order (A/S in (0.1, 1])


finite = st.floats(-1e3, 1e3).filter(lambda v: v == 0.0 or abs(v) > 1e-100)  # no subnormal results


@settings(deadline=None, max_examples=400)
@given(st.floats(-3, 3), st.floats(-2, 2), st.floats(0.1, 1e4), st.floats(0.002, 0.5))
def test_fhan_equals_han_2009(m, n, r, h0):
    # test points chosen by their switch variables, y = m d0 and a = n d (d0 = r h0^2, d = r h0), so the
    # interior of every branch is visited; the paper's map from (g1, g2) to (y, a) is inverted for that
    d, d0 = r * h0, r * h0 * h0
    y = m * d0
    g2 = n * d - (0.5 * (math.sqrt(d * d + 8 * r * abs(y)) - d) * np.sign(y) if abs(y) > d0 else y / h0)
    g1 = y - h0 * g2
    ours, ref = fhan(g1, g2, r, h0), _han2009(g1, g2, r, h0)
    assert ours == pytest.approx(ref, rel=1e-9, abs=1e-9 * r)


@hyp
@given(finite, finite, st.floats(0.1, 1e4), st.floats(0.002, 0.5), st.integers(-40, 40))
def test_fhan_homogeneous_exactly_for_powers_of_two(g1, g2, r, h0, e):
    s = 2.0**e
    assert fhan(s * g1, s * g2, s * r, h0) == s * fhan(g1, g2, r, h0)


@hyp
@given(st.integers(-6, 6), st.floats(1.0, 9.99), st.floats(-100, 100), st.floats(0.02, 0.5),
       st.floats(0, 2 * math.pi))
def test_tracks_sines_of_any_magnitude(e, mant, off, f, ph):
    """Amplitudes 1e-6..1e7 m/Pa-like with scale = the amplitude's order, offsets to 100 A, 0.02-0.5 Hz.

    Bound: after the lag (value 9, derivative 8.5 samples = 2 h0/h - 1, - 1.5), the error is at most
    (w h0)^2 of A (value) and of A w (derivative), i.e. <= 2.5 % at 0.5 Hz. Reason: on fhan's linear
    band the T-D is a double pole at 1/h0, gain 1/(1 + (w h0)^2) ~ 1 - (w h0)^2. Measured worst over a
    grid of this range: 0.79 (w h0)^2 (1.95 % at 0.5 Hz), so the bound is tight to a factor 1.27.
    """
    a, scale = _magnitude(e, mant)
    w = 2 * math.pi * f
    n = SETTLE + int(max(1.0 / (f * H), 200))
    t = np.arange(n) * H
    out = td_filter(off * a + a * np.sin(w * t + ph), R, H0, H, scale)[SETTLE:]
    ts = t[SETTLE:]
    tol = (w * H0) ** 2
    val_err = np.max(np.abs(out[:, 0] - (off * a + a * np.sin(w * (ts - 9 * H) + ph))))
    der_err = np.max(np.abs(out[:, 1] - a * w * np.cos(w * (ts - 8.5 * H) + ph)))
    assert val_err <= tol * a
    assert der_err <= tol * a * w


@hyp
@given(st.integers(-6, 6), st.floats(1.0, 9.99), st.floats(-100, 100), st.floats(0.02, 2.0),
       st.floats(0, 2 * math.pi), st.floats(0.02, 0.1))
def test_equals_exact_linear_response_up_to_2hz(e, mant, off, f, ph, h0):
    """With A / scale <= 0.1 the T-D stays on fhan's linear band: outputs equal the analytic response."""
    a, scale = _magnitude(e, mant)
    scale *= 10.0
    w = 2 * math.pi * f
    hv, hd = _linear_response(h0, H, f)
    n = SETTLE + int(20 * h0 / H) + 200
    t = np.arange(n) * H
    out = td_filter(off * a + a * np.sin(w * t + ph), R, h0, H, scale)[n - 200:]
    ts = t[n - 200:]
    want_v = off * a + a * abs(hv) * np.sin(w * ts + ph + np.angle(hv))
    want_d = a * abs(hd) * np.sin(w * ts + ph + np.angle(hd))
    np.testing.assert_allclose(out[:, 0], want_v, rtol=0, atol=1e-9 * a * (1 + abs(off)))
    np.testing.assert_allclose(out[:, 1], want_d, rtol=0, atol=1e-9 * a * w * (1 + abs(off)))


@pytest.mark.parametrize("f", [0.1, 0.5, 1.0, 2.0])
def test_td_lag_matches_linear_theory(f):
    lag = td_lag(R, H0, H, f, amplitude=0.1)
    hv, hd = _linear_response(H0, H, f)
    wh = 2 * math.pi * f * H
    assert lag.value_lag == pytest.approx(-np.angle(hv) / wh, abs=1e-6)
    assert lag.derivative_lag == pytest.approx((math.pi / 2 - np.angle(hd)) / wh, abs=1e-6)
    assert lag.value_gain == pytest.approx(abs(hv), abs=1e-9)
    assert lag.derivative_gain == pytest.approx(abs(hd) / (2 * math.pi * f), abs=1e-9)


@pytest.mark.parametrize("f, vlag, dlag, gain", [(0.1, 9.00, 8.50, 0.999), (0.5, 8.94, 8.44, 0.981),
                                                 (1.0, 8.97, 8.47, 0.923), (2.0, 10.54, 10.04, 0.704)])
def test_td_lag_docstring_table(f, vlag, dlag, gain):
    lag = td_lag(R, H0, H, f)  # paper's settings, unit amplitude
    assert lag.value_lag == pytest.approx(vlag, abs=0.005)
    assert lag.derivative_lag == pytest.approx(dlag, abs=0.005)
    assert lag.value_gain == pytest.approx(gain, abs=0.0005)


def test_td_lag_rejects_bad_frequency():
    with pytest.raises(ValueError, match="freq"):
        td_lag(R, H0, H, 60.0)


def test_unscaled_paper_settings_fail_on_pressure_sized_signals():
    """The trap: r = 100 is an acceleration limit of 100 Pa/s^2 on a signal of 1e7 Pa."""
    f = 0.5
    w = 2 * math.pi * f
    t = np.arange(1000) * H
    x = 1.2e7 + 1e7 * np.sin(w * t)
    true_d = 1e7 * w * np.cos(w * (t - 8.5 * H))
    bad = td_filter(x, R, H0, H, 1.0)[SETTLE:, 1]
    good = td_filter(x, R, H0, H, 1e7)[SETTLE:, 1]
    assert np.max(np.abs(bad - true_d[SETTLE:])) > 0.9 * 1e7 * w  # derivative essentially lost
    assert np.max(np.abs(good - true_d[SETTLE:])) <= (w * H0) ** 2 * 1e7 * w


def _signal(rng, n, shape, scale):
    return scale * (np.cumsum(rng.normal(size=(n,) + shape), axis=0) * 0.05 + rng.normal(size=shape))


@hyp
@given(st.integers(0, 2**32 - 1), st.floats(-6, 7), st.integers(-30, 30), st.floats(0.3, 3.0))
def test_homogeneity(seed, log_s0, e, factor):
    rng = np.random.default_rng(seed)
    s0 = 10.0**log_s0
    x = _signal(rng, 300, (), s0)
    base = td_filter(x, R, H0, H, s0)
    s = 2.0**e
    assert np.array_equal(td_filter(s * x, R, H0, H, s * s0), s * base)  # powers of two: exact
    s = factor * 10.0**e
    scaled = td_filter(s * x, R, H0, H, s * s0)  # any factor: equal to rounding (1e-12 of the range)
    for col in (0, 1):
        np.testing.assert_allclose(scaled[:, col], s * base[:, col], rtol=0,
                                   atol=1e-12 * s * np.max(np.abs(base[:, col])))


@hyp
@given(st.integers(0, 2**32 - 1), st.integers(1, 4), st.integers(1, 4))
def test_batch_equals_single_bit_for_bit(seed, n_rigs, n_ch):
    rng = np.random.default_rng(seed)
    r = 10.0 ** rng.uniform(0, 3, n_ch)
    h0 = rng.uniform(0.01, 0.2, n_ch)
    scale = 10.0 ** rng.uniform(-6, 7, n_ch)
    x = _signal(rng, 200, (n_rigs, n_ch), scale)
    x_copy, r_copy, h0_copy, s_copy = x.copy(), r.copy(), h0.copy(), scale.copy()
    mu = np.zeros((n_rigs, n_ch, 2))
    mu[:, :, 0] = x[0]
    batch = np.empty((200, n_rigs, n_ch, 2))
    for k in range(200):
        td_step_batch(mu, x[k], r, h0, H, scale)
        batch[k] = mu
    for i in range(n_rigs):
        tdc = TrackingDifferentiator(r=r, h0=h0, h=H, scale=scale, n_channels=n_ch)
        cls = np.array([np.stack(tdc.update(x[k, i])) for k in range(200)])  # (n, 2, n_ch)
        assert np.array_equal(cls.transpose(0, 2, 1), batch[:, i])
        for j in range(n_ch):
            single = np.array([x[0, i, j], 0.0])
            for k in range(200):
                td_step(single, x[k, i, j], r[j], h0[j], H, scale[j])
                assert np.array_equal(single, batch[k, i, j])
            assert np.array_equal(td_filter(x[:, i, j], r[j], h0[j], H, scale[j]), batch[:, i, j])
    for a, b in [(x, x_copy), (r, r_copy), (h0, h0_copy), (scale, s_copy)]:
        assert np.array_equal(a, b)  # inputs not mutated


def test_derivative_is_forward_difference_of_value():
    x = np.sin(np.arange(500) * H * 3.0) + 0.01 * np.random.default_rng(0).normal(size=500)
    out = td_filter(x, R, H0, H, 1.0)
    np.testing.assert_allclose(out[:-1, 1], np.diff(out[:, 0]) / H, rtol=0, atol=1e-9)


def test_first_update_initialises_at_first_sample_and_reset():
    td = TrackingDifferentiator(scale=[1e-2, 1e7], n_channels=2)
    v, d = td.update([0.03, 6e6])
    assert v.tolist() == [0.03, 6e6] and d.tolist() == [0.0, 0.0]
    td.update([0.04, 7e6])
    td.reset([1.0, 2.0])
    assert td.state[0, :, 0].tolist() == [1.0, 2.0] and td.state[0, :, 1].tolist() == [0.0, 0.0]
    td.reset()
    v, d = td.update([5.0, 5e6])
    assert v.tolist() == [5.0, 5e6] and d.tolist() == [0.0, 0.0]


def _feed(td, xs):
    return [np.stack(td.update(x)) for x in xs]


def test_deterministic_pickle_and_copy():
    xs = _signal(np.random.default_rng(3), 200, (3,), np.array([1e-2, 1e7, 1e-4]))
    make = lambda: TrackingDifferentiator(scale=[0.1, 1.2e7, 1e-3], n_channels=3)  # noqa: E731
    a, b = make(), make()
    assert np.array_equal(_feed(a, xs), _feed(b, xs))  # deterministic
    c = make()
    _feed(c, xs[:100])
    d = pickle.loads(pickle.dumps(c))
    e = copy.deepcopy(c)
    rest_c = _feed(c, xs[100:])
    assert np.array_equal(rest_c, _feed(d, xs[100:]))
    assert np.array_equal(rest_c, _feed(e, xs[100:]))
    assert not np.shares_memory(e.state, c.state)  # independent copies


def test_update_does_not_mutate_input():
    x = np.array([0.1, 2e6])
    td = TrackingDifferentiator(scale=[0.1, 1e7], n_channels=2)
    v, _ = td.update(x)
    v[:] = 99.0  # returned arrays are copies, not views of the state
    td.update(x)
    assert x.tolist() == [0.1, 2e6] and td.state[0, 0, 0] != 99.0


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), [1.0, float("nan")]])
def test_non_finite_input_raises(bad):
    td = TrackingDifferentiator(n_channels=2)
    td.update([1.0, 2.0])
    before = td.state.copy()
    with pytest.raises(ValueError, match="finite"):
        td.update(bad)
    with pytest.raises(ValueError, match="finite"):
        td.reset(bad)
    assert np.array_equal(td.state, before) and td.initialised  # a rejected sample changes nothing


@pytest.mark.parametrize("kw, name", [({"r": 0.0}, "r"), ({"h0": -1.0}, "h0"), ({"scale": float("nan")}, "scale"),
                                      ({"h0": 0.005}, "h0"), ({"h": 0.0}, "h"), ({"n_channels": 0}, "n_channels"),
                                      ({"scale": [1.0, 2.0, 3.0]}, "scale")])
def test_bad_hyperparameters_raise(kw, name):
    with pytest.raises(ValueError, match=name):
        TrackingDifferentiator(**kw, **({} if "n_channels" in kw else {"n_channels": 2}))


def test_wrong_shape_raises():
    with pytest.raises(ValueError, match="shape"):
        TrackingDifferentiator(n_channels=2).update([1.0, 2.0, 3.0])


def test_config_scales_from_rig_config():
    from hydromon.contract import RigConfig

    cfg = RigConfig()
    s = config_scales(cfg, omega=10.0)
    assert s["x1"] == cfg.x1_span and s["x3"] == s["x4"] == cfg.p_span and s["x5"] == cfg.x5_span
    assert s["x2"] == cfg.x1_span * 10.0 and s["x6"] == cfg.x5_span * 10.0
