"""Tests of monitor.grading: Table 3 bands, clamping, SE gating, hysteresis, fusion, confidence,
batch == single rig, pickling, ranges files."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import norm

from hydromon.contract import PARAM_NAMES
from monitor.grading import BatchGrader, Grader, ParamRange, Ranges, grade_kernel, grade_name, grade_of_values
from plant_sim.degradation import degrade
from plant_sim.params import PlantParams

TRUE = PlantParams().identified()  # a healthy rig: every graded parameter in grade 0
ZERO = dict.fromkeys(PARAM_NAMES, 0.0)


def one(name, value):
    return grade_of_values({name: value})


# --- Table 3 bands -------------------------------------------------------------------------

TABLE3_CASES = {
    # value -> grade; a value on an edge belongs to the better grade ((10, 20] in Table 3)
    "f_c": [(0.0, 0), (4.0, 0), (10.0, 0), (10.001, 1), (20.0, 1), (20.001, 2), (45.0, 2),
            (45.001, 3), (75.0, 3), (75.001, 4), (120.0, 4), (500.0, 4)],
    "B_fv": [(5000.0, 0), (6020.0, 0), (6075.0, 0), (6075.01, 1), (6150.0, 1), (6150.01, 2),
             (6250.0, 2), (6250.01, 3), (6400.0, 3), (6400.01, 4), (6600.0, 4), (9000.0, 4)],
    # the valve on its static gain [m/V]: Table 3's K_sv omega^2 edges / 1e4
    "K_sv": [(5e-4, 0), (2.6e-4, 0), (2.2e-4, 0), (2.199e-4, 1), (1.7e-4, 1), (1.699e-4, 2),
             (1.4e-4, 2), (1.399e-4, 3), (1.0e-4, 3), (0.999e-4, 4), (0.5e-4, 4), (0.01e-4, 4)],
    "C_ip": [(0.0, 0), (3e-11, 0), (1e-10, 0), (1.001e-10, 4), (3e-10, 4), (1e-8, 4)],
    "C_ep": [(0.0, 0), (1e-12, 0), (1e-10, 0), (1.001e-10, 4), (3e-10, 4)],
}


@pytest.mark.parametrize("name", sorted(TABLE3_CASES))
def test_table3_bands_and_clamping(name):
    for value, grade in TABLE3_CASES[name]:
        assert one(name, value) == grade, (name, value)


def test_table3_file_equals_paper():
    r = Ranges.paper()
    assert set(r.params) == {"K_sv_omega_sv2", "f_c", "B_fv", "C_ip", "C_ep"}
    assert r.params["K_sv_omega_sv2"] == ParamRange(direction="falling", edges=(2.2, 1.7, 1.4, 1.0))
    assert r.params["f_c"] == ParamRange(direction="rising", edges=(10, 20, 45, 75))
    assert r.params["B_fv"] == ParamRange(direction="rising", edges=(6075, 6150, 6250, 6400))
    for n in ("C_ip", "C_ep"):
        assert r.params[n] == ParamRange(direction="rising", fault_threshold=1e-10)


def test_default_ranges_are_table3_with_the_valve_on_its_static_gain():
    paper, ours = Ranges.paper(), Ranges.default()
    assert set(ours.params) == set(paper.params) - {"K_sv_omega_sv2"} | {"K_sv"}
    assert all(ours.params[k] == paper.params[k] for k in paper.params if k != "K_sv_omega_sv2")
    assert ours.params["K_sv"] == ParamRange(direction="falling", edges=(2.2e-4, 1.7e-4, 1.4e-4, 1.0e-4))
    # on the paper's rigs (its degradation holds omega_sv at 100 rad/s) the two grade alike;
    # exactly on a band edge (severity 0.2, 0.4, ...) the product K_sv omega^2 rounds either way
    for s in np.linspace(0.0, 1.0, 401):
        if np.min(np.abs(s - np.arange(6) * 0.2)) < 1e-9:
            continue
        true = degrade(float(s)).identified()
        assert grade_of_values(true, ours) == grade_of_values(true, paper), s


def test_cdw_is_ungraded_by_default():
    with pytest.raises(ValueError, match="graded"):
        grade_of_values({"CdW_sqrt_rho": 1e-4})
    assert grade_of_values({**TRUE, "CdW_sqrt_rho": 1e-9}) == 0


@pytest.mark.parametrize("row, paper", [
    # paper Table 4: K_sv w^2, CdW/sqrt(rho) x1e4, f_c, B+f_v, C_ip x1e11, C_ep x1e13, grade
    ((1.96, 5.51, 14.64, 6098.00, 2.94, 8.68), "sub-health"),
    ((2.49, 5.70, 4.67, 6021.31, 3.01, 2.45), "health"),
    ((0.79, 3.74, 99.48, 6496.67, 29.15, 3010), "fault"),
    ((1.6, 4.74, 29.78, 6183.32, 2.99, 2.06), "average"),
    ((1.19, 4.75, 60.44, 6297.15, 3.03, 3.20), "deterioration"),
])
def test_table4_groups_get_the_papers_grade(row, paper):
    k, cdw, fc, b, cip, cep = row
    v = {"K_sv_omega_sv2": k, "CdW_sqrt_rho": cdw * 1e-4, "f_c": fc, "B_fv": b,
         "C_ip": cip * 1e-11, "C_ep": cep * 1e-13}
    assert grade_name(grade_of_values(v, Ranges.paper())) == paper
    v["K_sv"] = v.pop("K_sv_omega_sv2") / 1e4  # the paper's omega_sv^2
    assert grade_name(grade_of_values(v)) == paper


def test_fused_level_is_the_worst():
    assert grade_of_values({**TRUE, "f_c": 30.0}) == 2
    assert grade_of_values({**TRUE, "f_c": 30.0, "K_sv": 1.2e-4}) == 3
    assert grade_of_values({**TRUE, "f_c": 30.0, "C_ep": 3e-10}) == 4


def test_grade_of_values_rejects_nonfinite():
    with pytest.raises(ValueError, match="f_c"):
        grade_of_values({**TRUE, "f_c": math.nan})


# --- hysteresis ----------------------------------------------------------------------------

@pytest.mark.parametrize("name, edge, steps", [
    # (value, expected grade) after starting on the worse side of the edge; margins: f_c 0.4 N,
    # K_sv 3.4e-6, C_ip 2e-12, B_fv min(123, half of 75) = 37.5 N s/m
    ("f_c", 20.0, [(19.7, 2), (20.3, 2), (19.5, 1), (20.3, 1), (19.7, 1), (20.5, 2)]),
    ("K_sv", 1.7e-4, [(1.73e-4, 2), (1.67e-4, 2), (1.735e-4, 1), (1.67e-4, 1), (1.665e-4, 2)]),
    ("C_ip", 1e-10, [(0.985e-10, 4), (0.979e-10, 0), (1.015e-10, 0), (1.021e-10, 4)]),
    ("B_fv", 6150.0, [(6120.0, 2), (6180.0, 2), (6110.0, 1), (6185.0, 1), (6190.0, 2),
                      (6100.0, 1)]),  # 6100 is past the middle of (6075, 6150]
])
def test_hysteresis_no_flap_then_real_move(name, edge, steps):
    g = Grader()
    worse = {"K_sv": -1}.get(name, 1)
    start = one(name, edge * (1 + 0.005 * worse))
    seen = {g.update({**TRUE, name: edge * (1 + 0.005 * worse * (-1) ** i)}, ZERO, True)
            .param_levels[name] for i in range(40)}  # +-0.5 % around the edge
    assert seen == {start}
    for value, want in steps:
        assert g.update({**TRUE, name: value}, ZERO, True).param_levels[name] == want, value


def test_margins_are_capped_at_half_a_band():
    a = Ranges.default().to_arrays(0.02)
    m = dict(zip(a.names, a.margins))
    np.testing.assert_allclose(m["f_c"], [0.2, 0.4, 0.9, 1.5])
    np.testing.assert_allclose(m["B_fv"], [37.5, 37.5, 50.0, 75.0])
    np.testing.assert_allclose(m["K_sv"], [4.4e-6, 3.4e-6, 2.8e-6, 2e-6])
    np.testing.assert_allclose(m["C_ip"], [2e-12] * 4)


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(["f_c", "B_fv", "K_sv"]), st.integers(1, 3),
       st.floats(0.001, 0.499), st.booleans(), st.integers(-1, 4), st.floats(0.0, 0.9))
def test_value_past_band_middle_is_graded_there(name, k, d, upper, held, margin):
    # the cap's promise: once a value is past the middle of inner band k, coming from the
    # side of the held band, it is graded k (any margin)
    e = Ranges.default().params[name].edges
    frac = {True: 0.5 - d, False: 0.5 + d}[held > k] if held != k and held >= 0 else (
        0.5 + d if upper else 0.5 - d)
    g = Grader(margin=margin)
    g.band[:] = held
    value = e[k - 1] + frac * (e[k] - e[k - 1])  # frac runs from the better to the worse edge
    assert g.update({**TRUE, name: value}, ZERO, True).param_levels[name] == k


def test_without_margin_it_flaps():
    g = Grader(margin=0.0)
    seen = {g.update({**TRUE, "f_c": 20.0 * (1 + 0.005 * (-1) ** i)}, ZERO, True).level
            for i in range(4)}
    assert seen == {1, 2}


def test_hysteresis_crosses_several_bands_at_once():
    g = Grader()
    g.update({**TRUE, "f_c": 5.0}, ZERO, True)
    assert g.update({**TRUE, "f_c": 100.0}, ZERO, True).level == 4
    assert g.update({**TRUE, "f_c": 30.0}, ZERO, True).level == 2


# --- SE gating, convergence ----------------------------------------------------------------

def test_se_gating_f_c():
    g = Grader()
    se = {**ZERO, "f_c": 1.0}
    r = g.update({**TRUE, "f_c": 7.0}, se, True)        # 7 +- 2: inside health
    assert r.param_levels["f_c"] == 0 and r.level == 0
    r = g.update({**TRUE, "f_c": 7.0}, {**se, "f_c": 4.0}, True)   # [-1, 15]: two bands
    assert r.param_levels["f_c"] == 0
    r = g.update({**TRUE, "f_c": 14.0}, {**se, "f_c": 4.0}, True)  # [6, 22]: three bands
    assert r.param_levels["f_c"] == -1
    assert r.level == 0 and r.confidence == pytest.approx(4 / 5)
    assert g.band[g._batch.names.index("f_c")] == 0  # memory kept while not placed


def test_se_gating_two_level_and_nonfinite():
    g = Grader()
    r = g.update({**TRUE, "C_ip": 8e-11}, {**ZERO, "C_ip": 2e-11}, True)
    assert r.param_levels["C_ip"] == -1                  # [4e-11, 1.2e-10] straddles 1e-10
    r = g.update({**TRUE, "C_ip": 8e-11}, {**ZERO, "C_ip": 5e-12}, True)
    assert r.param_levels["C_ip"] == 0
    for bad in (math.inf, math.nan):
        r = g.update({**TRUE, "B_fv": 6000.0}, {**ZERO, "B_fv": bad}, True)
        assert r.param_levels["B_fv"] == -1
    r = g.update({**TRUE, "B_fv": math.nan}, ZERO, True)
    assert r.param_levels["B_fv"] == -1


def test_nothing_placed_is_unknown():
    huge = dict.fromkeys(PARAM_NAMES, 1e6)
    r = Grader().update(TRUE, huge, True)
    assert r.level == -1 and r.grade == "unknown" and r.confidence == 0.0


def test_unknown_until_converged_and_state_untouched():
    g = Grader()
    for _ in range(3):
        r = g.update({**TRUE, "f_c": 50.0}, ZERO, False)
        assert r.level == -1 and r.grade == "unknown" and r.confidence == 0.0
        assert set(r.param_levels.values()) == {-1}
        assert (g.band == -1).all()
    r = g.update({**TRUE, "f_c": 50.0}, ZERO, True)
    assert r.level == 3 and r.grade == "deterioration" and r.param_grades["f_c"] == "deterioration"


def test_bad_inputs_raise():
    g = Grader()
    with pytest.raises(ValueError, match="negative"):
        g.update(TRUE, {**ZERO, "f_c": -1.0}, True)
    with pytest.raises(ValueError, match="shape"):
        g.update(np.zeros(3), np.zeros(3), True)
    with pytest.raises(ValueError, match="f_x"):
        g.update({**TRUE, "f_x": 1.0}, ZERO, True)
    with pytest.raises(ValueError, match="converged"):
        BatchGrader(2).update(np.zeros((2, len(PARAM_NAMES))), np.zeros((2, len(PARAM_NAMES))), [True])
    for kw in ({"z": 0.0}, {"z": math.inf}, {"margin": -0.1}, {"margin": 1.0}):
        with pytest.raises(ValueError):
            Grader(**kw)
    with pytest.raises(ValueError, match="n_rigs"):
        BatchGrader(0)


def test_inputs_not_mutated():
    v = np.array([TRUE[n] for n in PARAM_NAMES])
    s = np.full(len(PARAM_NAMES), 0.1)
    v0, s0 = v.copy(), s.copy()
    Grader().update(v, s, True)
    assert (v == v0).all() and (s == s0).all()


# --- confidence ----------------------------------------------------------------------------

def test_confidence_exact_values_is_one():
    assert Grader().update(TRUE, ZERO, True).confidence == 1.0


def test_confidence_formula_against_scipy():
    # f_c 30 +- 1.5 (average, L = 2), K_sv 1.85 +- 0.05 (sub-health), B_fv 6100 +- 10 (sub);
    # each +-2 SE interval inside one band, so all three are placed
    v = {**TRUE, "f_c": 30.0, "K_sv": 1.85e-4, "B_fv": 6100.0}
    s = {**ZERO, "f_c": 1.5, "K_sv": 0.05e-4, "B_fv": 10.0}
    r = Grader().update(v, s, True)
    assert r.level == 2
    p_le2 = norm.cdf(45, 30, 1.5) * norm.sf(1.4e-4, 1.85e-4, 0.05e-4) * norm.cdf(6250, 6100, 10)
    p_le1 = norm.cdf(20, 30, 1.5) * norm.sf(1.7e-4, 1.85e-4, 0.05e-4) * norm.cdf(6150, 6100, 10)
    assert r.confidence == pytest.approx(p_le2 - p_le1, rel=1e-12)


def test_interval_straddling_an_edge_is_not_placed_when_another_parameter_is():
    # f_c 21 +- 1.5 straddles 20: ambiguous, must not decide the worst-of fusion
    v = {**TRUE, "f_c": 21.0, "K_sv": 1.85e-4}
    s = {**ZERO, "f_c": 1.5, "K_sv": 0.05e-4}
    r = Grader().update(v, s, True)
    assert r.param_levels["f_c"] == -1 and r.level == 1


def test_fallback_grades_the_most_precise_straddling_parameter():
    # every graded parameter straddles an edge: the one with the smallest SE relative to its
    # band's width (K_sv: 0.02 / 0.5) is graded at its value
    v = {"f_c": 21.0, "K_sv": 1.71e-4, "B_fv": 6150.0, "C_ip": 3e-11, "C_ep": 0.0}
    s = {"f_c": 1.5, "K_sv": 0.02e-4, "B_fv": 20.0, "C_ip": 1e-10, "C_ep": 1e-10}
    r = Grader().update(v, s, True)
    assert r.level == 1 and r.param_levels["K_sv"] == 1
    assert r.param_levels["f_c"] == -1


def test_confidence_held_level_past_edge_with_exact_values_is_zero():
    g = Grader()
    g.update({**TRUE, "f_c": 19.9}, ZERO, True)
    r = g.update({**TRUE, "f_c": 20.1}, ZERO, True)
    assert r.level == 1 and r.confidence == 0.0


# --- batch == single, pickling ---------------------------------------------------------------

def _random_stream(rng, n_rigs, n_steps):
    base = np.array([TRUE[n] for n in PARAM_NAMES])
    # wander over the bands of f_c, B_fv, K_sv and C_ip, hugging edges often
    fc = rng.choice([10.0, 20.0, 45.0, 75.0, 7.0], size=(n_steps, n_rigs))
    vals = np.tile(base, (n_steps, n_rigs, 1))
    i = PARAM_NAMES.index
    vals[..., i("f_c")] = fc * (1 + rng.normal(0, 0.02, fc.shape))
    vals[..., i("B_fv")] = 6150.0 * (1 + rng.normal(0, 0.01, fc.shape))
    vals[..., i("K_sv")] = rng.uniform(0.3e-4, 3.0e-4, fc.shape)
    vals[..., i("C_ip")] = 10 ** rng.uniform(-11, -9, fc.shape)
    se = np.abs(vals) * rng.uniform(0, 0.05, vals.shape)
    se[rng.random(se.shape) < 0.05] = np.inf
    conv = rng.random((n_steps, n_rigs)) < 0.8
    return vals, se, conv


def test_batch_equals_single_rig_graders():
    rng = np.random.default_rng(3)
    n_rigs, n_steps = 12, 60
    vals, se, conv = _random_stream(rng, n_rigs, n_steps)
    batch = BatchGrader(n_rigs)
    singles = [Grader() for _ in range(n_rigs)]
    levels = set()
    for t in range(n_steps):
        b = batch.update(vals[t], se[t], conv[t])
        for r in range(n_rigs):
            s = singles[r].update(vals[t, r], se[t, r], conv[t, r])
            assert b.rig(r) == s
            assert (batch.band[r] == singles[r].band).all()
            levels.add(s.level)
    assert levels == {-1, 0, 1, 2, 3, 4}  # the stream exercised every grade


def test_pickle_resumes_identically():
    rng = np.random.default_rng(5)
    vals, se, conv = _random_stream(rng, 1, 40)
    g = Grader()
    for t in range(20):
        g.update(vals[t, 0], se[t, 0], conv[t, 0])
    h = pickle.loads(pickle.dumps(g))
    for t in range(20, 40):
        args = (vals[t, 0], se[t, 0], conv[t, 0])
        assert g.update(*args) == h.update(*args)
    fresh = Grader()
    assert (fresh.band == -1).all() and not (g.band == -1).all()


# --- ranges files ----------------------------------------------------------------------------


# --- properties ----------------------------------------------------------------------------

GRADED = {"f_c": (0.0, 200.0), "B_fv": (5900.0, 6800.0), "K_sv": (0.1e-4, 3.0e-4),
          "C_ip": (0.0, 1e-9), "C_ep": (0.0, 1e-9)}


@st.composite
def rig_and_pair(draw):
    base = {n: draw(st.floats(*GRADED[n])) for n in GRADED}
    name = draw(st.sampled_from(sorted(GRADED)))
    a, b = sorted((draw(st.floats(*GRADED[name])), draw(st.floats(*GRADED[name]))))
    return base, name, a, b


@settings(max_examples=200, deadline=None)
@given(rig_and_pair())
def test_grade_is_monotone_along_direction(case):
    base, name, a, b = case
    ga = grade_of_values({**base, name: a})
    gb = grade_of_values({**base, name: b})
    assert (ga <= gb) if Ranges.default().params[name].direction == "rising" else (ga >= gb)


@settings(max_examples=200, deadline=None)
@given(rig_and_pair(), st.integers(-1, 4))
def test_hysteresis_grade_is_monotone_for_a_given_state(case, held):
    base, name, a, b = case
    out = []
    for x in (a, b):
        g = Grader()
        g.band[:] = held
        r = g.update({**base, name: x}, ZERO, True)
        out.append(r.param_levels[name])
        assert 0.0 <= r.confidence <= 1.0
        assert r.level == max(r.param_levels.values())
    rising = Ranges.default().params[name].direction == "rising"
    assert (out[0] <= out[1]) if rising else (out[0] >= out[1])


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(0.0, 0.2), min_size=len(PARAM_NAMES), max_size=len(PARAM_NAMES)), rig_and_pair())
def test_level_is_max_of_placed_and_confidence_bounded(rel_se, case):
    base, _, _, _ = case
    v = np.array([{**TRUE, **base}[n] for n in PARAM_NAMES])
    s = np.abs(v) * np.array(rel_se)
    lv, gr, conf = grade_kernel(v[None], s[None], np.ones(1, np.bool_),
                                *Ranges.default().to_arrays()[1:], 2.0,
                                np.full((1, len(Ranges.default().params)), -1, np.int64))
    placed = gr[0][gr[0] >= 0]
    # a parameter straddling exactly one edge is not placed but floors the level at its better side
    floor = -1
    ranges = Ranges.default()
    for name in ranges.params:
        i = PARAM_NAMES.index(name)
        ends = [grade_of_values({name: v[i] + d * 2.0 * s[i]}, ranges) for d in (-1.0, 1.0)]
        if abs(ends[0] - ends[1]) == 1:
            floor = max(floor, min(ends))
    assert lv[0] == max(placed.max() if placed.size else -1, floor)
    assert 0.0 <= conf[0] <= 1.0
    # the reason is always shown: some parameter has the grade the rig has
    assert lv[0] == -1 or lv[0] == gr[0].max()


def test_a_level_set_by_a_straddling_parameter_is_shown_on_it_with_a_confidence():
    # a parameter whose interval straddles a band edge (B + f_v on a paper-var record at severity
    # 0.53, 14 s) sets the level its interval proves, shows that level as its own grade (not
    # "unknown" beside better grades only), and the confidence is the chance that level is right
    import math

    e = Ranges.default().params["B_fv"].edges
    values = {**TRUE, "B_fv": e[2] + 40.0}  # 40 N s/m past the average|deterioration edge
    ses = dict.fromkeys(PARAM_NAMES, 0.0)
    ses["B_fv"] = 30.0  # +-2 SE reaches back over that edge only: not placed, a floor
    r = Grader().update(values, ses, True)
    assert r.level == 2  # at least average: what the interval proves
    assert r.param_levels["B_fv"] == 2  # the reason, shown
    # the chance that average is right: P(B + f_v in the average band), every other parameter certain
    def below(edge):
        return 0.5 * math.erfc((values["B_fv"] - edge) / (30.0 * math.sqrt(2.0)))

    assert r.confidence == pytest.approx(below(e[2]) - below(e[1]), rel=1e-9)  # 0.09
