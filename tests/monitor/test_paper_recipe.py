"""The paper's literal recipe (monitor.paper_recipe): accurate noise-free, biased under noise."""

import numpy as np
import pytest

from hydromon.contract import PARAM_NAMES
from monitor.paper_recipe import PaperRecipe, identify_paper
from monitor.pipeline import Pipeline
from plant_sim.noise import noise_model
from plant_sim.profiles import PaperIdentification
from plant_sim.simulate import simulate


@pytest.fixture(scope="module")
def clean_run():
    return simulate(PaperIdentification(), 10.0)


def _rel(est, true):
    return {k: (est[k] - true[k]) / true[k] for k in true if true[k] != 0}


def test_noise_free_table2_within_a_few_percent(clean_run):
    # measured: m -0.60 %, B_fv +0.01 %, f_c +1.35 %, chamber -0.07 %..+0.01 %, valve -0.07 %
    true = clean_run.params.identified()
    est = identify_paper(clean_run.samples)
    rel = _rel(est, true)
    tol = {"m": 0.01, "B_fv": 0.005, "f_c": 0.03, "K_t": 1e-3, "inv_beta_e": 2e-3,
           "CdW_sqrt_rho": 2e-3, "C_ip": 2e-3, "two_zeta_omega": 2e-3, "omega_sv2": 2e-3,
           "K_sv_omega_sv2": 2e-3, "K_sv": 2e-3}
    bad = {k: v for k, v in rel.items() if abs(v) > tol[k]}
    assert not bad, bad
    assert abs(est["C_ep"]) < 1e-14  # measured -1.3e-15 (true 0)


def test_stress_noise_biases_the_paper_recipe_not_ours():
    """At 'stress' noise the T-D derivatives in the regressors (chambers) and in the target
    (valve, -x6') bias the paper's estimates low on every seed; ours stay within 1 % (chambers)
    and 2 % (valve)."""
    for seed in (1, 2):
        run = simulate(PaperIdentification(), 10.0, noise=noise_model("stress"), seed=seed)
        true = run.params.identified()
        paper = _rel(identify_paper(run.samples), true)
        ours = _rel(Pipeline().run(run.samples)[1].params, true)
        # measured (seeds 1, 2): inv_beta_e -6.0/-5.7 %, CdW -4.2/-3.9 %, omega_sv2 -39/-45 %
        for k in ("inv_beta_e", "CdW_sqrt_rho", "C_ip"):
            assert paper[k] < -0.03, (seed, k, paper[k])
            assert abs(ours[k]) < 0.01, (seed, k, ours[k])
        # the valve within the stress target for K_sv omega^2 (2 %); measured with
        # iv_start 30: -1.0 % worst (seeds 1, 2), 0.87 % mean over seeds 0-9
        for k in ("two_zeta_omega", "omega_sv2", "K_sv_omega_sv2"):
            assert paper[k] < -0.25, (seed, k, paper[k])
            assert abs(ours[k]) < 0.02, (seed, k, ours[k])


def test_causal_history_and_prefix(clean_run):
    full = identify_paper(clean_run.samples, full=True)
    head = identify_paper(clean_run.samples[:600], full=True)
    assert full.history.shape == (1000, len(PARAM_NAMES))
    assert np.isnan(full.history[:100]).all() and np.isfinite(full.history[100:]).all()  # 1 s warm-up
    np.testing.assert_allclose(head.history[100:], full.history[100:600], rtol=1e-12)
    assert full.shift == pytest.approx(0.5, abs=0.01)
    assert list(full.params.values()) == list(full.history[-1])


def test_bad_input_is_refused(clean_run):
    s = clean_run.samples.copy()
    with pytest.raises(ValueError, match="N, 5"):
        identify_paper(s[:, :4])
    s[500, 2] = np.nan
    with pytest.raises(ValueError, match="sample 500"):
        identify_paper(s)
    with pytest.raises(ValueError, match="at least"):
        identify_paper(clean_run.samples[:50])
    with pytest.raises(ValueError, match="h0"):
        PaperRecipe(h0=-1.0)
