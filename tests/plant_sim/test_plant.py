"""plant_sim: equilibrium, flow-law signs, integrator accuracy, profiles, degradation, noise."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hydromon.contract import GRADES, RigConfig
from plant_sim.degradation import degrade, grade_of_severity, table4_group
from plant_sim.integrate import run_fleet
from plant_sim.model import derivatives, equilibrium_state, null_state, orifice_z, valve_flows
from plant_sim.noise import add_noise, noise_model
from plant_sim.params import P_CDW_RHO, P_PS, Effects, PlantParams, plant_vector
from plant_sim.profiles import PaperIdentification, PaperVariable, parse_profile
from plant_sim.simulate import command_grid, simulate


@settings(max_examples=25, deadline=None)
@given(x1=st.floats(0.0, 0.05), kt=st.floats(1e5, 2e6), fl=st.floats(0.0, 8000.0), fc=st.floats(0.0, 100.0))
def test_equilibrium_with_centred_spool_stays(x1, kt, fl, fc):
    cfg = RigConfig(F_L=fl)
    p = plant_vector(cfg, PlantParams(K_t=kt, f_c=fc, C_ep=0.0))
    x0 = equilibrium_state(p, x1)
    n = 200
    grid = np.full((1, n, 21), cfg.K_f * x1)  # ug = K_f x1: zero control error
    out = run_fleet(x0[None], p[None], grid, cfg.h, np.zeros(1, np.int64))[0]
    # stays put: rounding kicks the velocity off zero and the Coulomb term sign(x2) then
    # chatters by at most 2 f_c hs / m per substep (hs = 1 ms); a moving plant is off by mm/MPa
    chatter = 2 * fc * 1e-3 / 120.0 + 1e-7
    assert np.allclose(out[-1], x0, rtol=0, atol=[1e-7, chatter, 50.0, 50.0, 1e-10, 1e-7])


def test_equilibrium_refuses_external_leakage():
    p = plant_vector(RigConfig(), PlantParams(C_ep=1e-11))
    with pytest.raises(ValueError, match="C_ep"):
        equilibrium_state(p)


@settings(max_examples=200, deadline=None)
@given(xv=st.floats(-1e-3, 1e-3), p1=st.floats(0, 12e6), p2=st.floats(0, 12e6))
def test_flows_obey_orifice_signs(xv, p1, p2):
    p = plant_vector(RigConfig(), PlantParams())
    q1, q2 = valve_flows(xv, p1, p2, p)
    # spool right: supply -> chamber 1 (in, as p1 < p_s), chamber 2 -> tank (out)
    if xv > 0:
        assert q1 >= 0 and q2 >= 0
    elif xv < 0:
        assert q1 <= 0 and q2 <= 0
    else:
        assert q1 == 0 and q2 == 0
    # magnitude: the turbulent orifice law with C_d W / sqrt(rho)
    dp1 = (p[P_PS] - p1) if xv >= 0 else p1
    assert math.isclose(abs(q1), p[P_CDW_RHO] * abs(xv) * math.sqrt(2 * dp1), rel_tol=1e-12, abs_tol=1e-300)


def test_orifice_z_branches():
    z1, z2 = orifice_z(1e-4, 4e6, 7e6, 12e6)
    assert z1 == pytest.approx(math.sqrt(2 * 8e6)) and z2 == pytest.approx(math.sqrt(2 * 7e6))
    z1, z2 = orifice_z(-1e-4, 4e6, 7e6, 12e6)
    assert z1 == pytest.approx(math.sqrt(2 * 4e6)) and z2 == pytest.approx(math.sqrt(2 * 5e6))


def test_substep_error_table():
    """The figures quoted in plant_sim/integrate.py's docstring (max abs error vs 200 substeps)."""
    ref = simulate(PaperIdentification(), 10.0, substeps=200).states
    err1 = np.abs(simulate(PaperIdentification(), 10.0, substeps=1).states - ref).max(0)
    err10 = np.abs(simulate(PaperIdentification(), 10.0, substeps=10).states - ref).max(0)
    assert 1e-6 < err1[4] < 1e-5  # one step per sample: spool off by ~3.8 um
    assert err10[0] < 5e-7 and err10[2] < 20 and err10[4] < 3e-9
    assert np.all(err10 < err1 / 30)


def test_substeps_against_scipy_reference():
    from scipy.integrate import solve_ivp

    from plant_sim.model import derivatives

    cfg = RigConfig()
    # smooth plant (no Coulomb step) so a tight ODE reference exists
    params = PlantParams(f_c=0.0)
    p = plant_vector(cfg, params)
    prof = PaperIdentification()
    run = simulate(prof, 2.0, params=params)

    def f(t, x):
        out = np.empty(6)
        derivatives(x, float(prof(t)), x[0], p, out)
        return out

    sol = solve_ivp(f, (0, 2.0 - cfg.h), null_state(p), t_eval=run.t[:-1], rtol=1e-10, atol=[1e-12, 1e-12, 1e-3, 1e-3, 1e-14, 1e-12], method="LSODA")
    err = np.abs(sol.y.T - run.states[:-1]).max(0)
    assert err[0] < 1e-7 and err[4] < 1e-9 and err[2] < 5.0


def test_paper_variable_profile_levels():
    prof = PaperVariable(period=10.0)
    t = np.array([0.0, 2.49, 2.6, 5.1, 7.6, 9.9])
    base = prof(t) - 0.5 * np.sin(5 * np.pi * t)
    assert np.allclose(base, [2.5, 2.5, 2.0, 2.5, 2.0, 2.0])


def test_parse_profile_errors():
    assert parse_profile("paper-var:period=20").period == 20
    with pytest.raises(ValueError, match="unknown profile"):
        parse_profile("nope")
    with pytest.raises(ValueError, match="key=value"):
        parse_profile("steps:low")


@pytest.mark.parametrize("s", [0.0, 0.1, 0.25, 0.5, 0.7, 0.9, 1.0])
def test_degradation_moves_every_parameter_into_the_band_of_its_severity(s):
    from monitor.grading import grade_of_values

    assert GRADES[grade_of_values(degrade(s).identified())] == grade_of_severity(s)


def test_degradation_rejects_bad_severity():
    with pytest.raises(ValueError, match="severity"):
        degrade(1.5)


def test_table4_groups_match_the_paper_estimates():
    p = table4_group(3).identified()
    assert p["K_sv_omega_sv2"] == pytest.approx(0.79) and p["C_ep"] == pytest.approx(3.01e-10)


def test_noise_is_seeded_and_sized():
    clean = np.zeros((20000, 4))
    a = add_noise(clean, noise_model("realistic"), 3)
    assert np.array_equal(a, add_noise(clean, noise_model("realistic"), 3))
    assert np.allclose(a.std(0), [5e-6, 5e3, 5e3, 0.5e-6], rtol=0.03)
    stress = noise_model("stress")
    assert stress.x3 == pytest.approx(0.001 * RigConfig().p_span)
    with pytest.raises(ValueError):
        noise_model("loud")


def test_effects_change_the_plant():
    base = simulate(PaperIdentification(), 3.0).states
    span = np.ptp(base, axis=0)
    # largest change of any state, relative to its span over the run (measured 2026-11-23: 5.0 %,
    # 4.3 %, 72 %, 24 %, 2.8 %, 3.0 %); a tenth of it must show, so an effect that stopped
    # acting (or acts a thousandth as much) fails
    for eff, measured in ((Effects(load_offset=2000.0), 0.050), (Effects(dead_band=2e-5), 0.043),
                          (Effects(x_max=2e-4), 0.72), (Effects(supply_sag=5e9), 0.24),
                          (Effects(air_fraction=0.02), 0.028), (Effects(stribeck_F_s=50.0), 0.030)):
        change = (np.abs(simulate(PaperIdentification(), 3.0, effects=eff).states - base).max(axis=0) / span).max()
        assert change > 0.1 * measured, (eff, change)
    sat = simulate(PaperIdentification(), 3.0, effects=Effects(x_max=2e-4)).states
    assert np.abs(sat[:, 4]).max() <= 2e-4 + 1e-15


@settings(max_examples=50, deadline=None)
@given(v=st.floats(-0.05, 0.05), p1=st.floats(0, 12e6), p2=st.floats(0, 12e6), c_p=st.floats(1e-6, 1e-3))
def test_seal_friction_is_the_differential_pressure_times_c_p_against_the_motion(v, p1, p2, c_p):
    # F_seal = c_p |p1 - p2| sign(v) [N] enters the force balance: m dv/dt falls by exactly that
    x = np.array([0.01, v, p1, p2, 1e-5, 0.0])
    with_seal, without = np.empty(6), np.empty(6)
    derivatives(x, 0.5, 0.01, plant_vector(RigConfig(), PlantParams(), Effects(seal_friction=c_p)), with_seal)
    derivatives(x, 0.5, 0.01, plant_vector(RigConfig(), PlantParams()), without)
    drop = (without[1] - with_seal[1]) * PlantParams().m
    assert drop == pytest.approx(c_p * abs(p1 - p2) * np.sign(v), rel=1e-9, abs=1e-6)
    assert np.array_equal(np.delete(with_seal, 1), np.delete(without, 1))


def test_sensor_delay_in_recording_only():
    run = simulate(PaperIdentification(), 2.0, effects=Effects(sensor_delay=3))
    assert np.array_equal(run.measured[3:, 0], run.states[:-3, 0])
    clean = simulate(PaperIdentification(), 2.0)
    assert np.array_equal(run.states, clean.states)  # the loop did not see it
    inloop = simulate(PaperIdentification(), 2.0, effects=Effects(sensor_delay=3, sensor_delay_in_loop=True))
    assert not np.array_equal(inloop.states, clean.states)


def test_command_grid_shape():
    g = command_grid(PaperIdentification(), 5, 0.01, 10)
    assert g.shape == (4, 21) and g[0, 0] == pytest.approx(2.0)


@pytest.mark.parametrize("spec", ["chirp:sweep=0", "paper-var:period=0", "steps:period=-2", "paper-id:freq=nan",
                                  "steps:low=inf", "paper-id:amplitude=1e9", "multisine:freqs=1/0",
                                  "chirp:f1=-3"])
def test_parse_profile_refuses_values_that_simulate_to_nan_or_out_of_contract(spec):
    # before: chirp:sweep=0 was a ZeroDivisionError traceback mid-run, freq=nan / low=inf wrote a
    # CSV of NaN with exit 0, amplitude=1e9 wrote pressures of -1.8e13 Pa, period=0 was ignored
    with pytest.raises(ValueError, match="profile"):
        parse_profile(spec)


def test_parse_profile_accepts_the_documented_examples():
    for spec in ("paper-var", "paper-id", "steps:low=1.5,high=2.5", "chirp", "multisine",
                 "multisine:freqs=0.5/1/2", "paper-var:period=20", "steps:low=-3,high=3"):
        parse_profile(spec)
