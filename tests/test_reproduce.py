"""hydromon calibrate (section 4.1) and hydromon reproduce (Tables 2-4)."""

import json

import numpy as np
import pytest

from hydromon.cli import main
from hydromon.contract import PARAM_NAMES
from monitor.calibrate import RunResults, calibrate, label_runs, simulate_runs, x1_thresholds
from monitor.grading import Ranges
from monitor.pipeline import Pipeline
from plant_sim.degradation import TABLE4_PAPER_GRADES, table4_group
from plant_sim.profiles import PaperVariable
from plant_sim.simulate import simulate


# ---------------------------------------------------------------- calibrate
@pytest.fixture(scope="module")
def runs20():
    return simulate_runs(20)


def _monotone(r):
    d = np.diff(r.edges)
    return np.all(d > 0) if r.direction == "rising" else np.all(d < 0)


def test_calibrate_20_runs_gives_valid_monotone_ranges(runs20, tmp_path):
    cal = calibrate(runs20)
    assert set(cal.ranges.params) == set(Ranges.default().params)
    for name, r in cal.ranges.params.items():
        if r.edges is not None:
            assert _monotone(r), (name, r.edges)
    assert np.all(np.diff(cal.thresholds) < 0)
    np.testing.assert_array_equal(cal.labels, np.repeat(np.arange(5), 4))  # severity bands, 4 runs each
    p = tmp_path / "r.json"
    cal.ranges.save(p)
    assert Ranges.load(p) == cal.ranges
    # noise-free, the calibrated edges land near Table 3's (the degradation follows Table 3)
    np.testing.assert_allclose(cal.ranges.params["f_c"].edges, [10, 20, 45, 75], rtol=0.05)
    np.testing.assert_allclose(cal.ranges.params["K_sv_omega_sv2"].edges, [2.2, 1.7, 1.4, 1.0], rtol=0.02)


def test_calibrated_ranges_grade_table4_like_the_paper(runs20):
    ranges = calibrate(runs20).ranges
    for g in range(1, 6):
        run = simulate(PaperVariable(), 10.0, params=table4_group(g))
        assert Pipeline(ranges=ranges).run(run.samples)[1].grade == TABLE4_PAPER_GRADES[g]


def _synthetic(n=10):
    sev = (np.arange(n) + 0.5) / n
    params = np.zeros((n, len(PARAM_NAMES)))
    params[:, PARAM_NAMES.index("f_c")] = 100 * sev  # rising
    params[:, PARAM_NAMES.index("B_fv")] = 6000 + 500 * sev
    params[:, PARAM_NAMES.index("K_sv_omega_sv2")] = 3 - 2 * sev  # falling
    params[:, PARAM_NAMES.index("C_ip")] = np.where(sev > 0.8, 3e-10, 3e-11)
    params[:, PARAM_NAMES.index("C_ep")] = np.where(sev > 0.8, 3e-10, 0.0)
    return RunResults(sev, 0.04 - 0.01 * sev, params, np.ones(n, bool))


def test_calibrate_is_midpoints_between_labels():
    cal = calibrate(_synthetic())
    # runs at s = 0.05, 0.15 | 0.25, 0.35 | ...: f_c edge between 15 and 25 -> 20
    np.testing.assert_allclose(cal.ranges.params["f_c"].edges, [20, 40, 60, 80])
    np.testing.assert_allclose(cal.ranges.params["K_sv_omega_sv2"].edges, [2.6, 2.2, 1.8, 1.4])
    assert cal.ranges.params["K_sv_omega_sv2"].direction == "falling"
    assert cal.ranges.params["C_ip"].fault_threshold == pytest.approx(1.65e-10)
    assert cal.ranges.params["C_ep"].fault_threshold == pytest.approx(1.5e-10)
    np.testing.assert_allclose(cal.thresholds, [0.038, 0.036, 0.034, 0.032])
    np.testing.assert_array_equal(label_runs([0.039, 0.0359, 0.001], cal.thresholds), [0, 2, 4])


def test_calibrate_refuses_unusable_runs():
    r = _synthetic()
    with pytest.raises(ValueError, match="do not fall"):
        x1_thresholds(r.severity, 0.01 + 0.01 * r.severity)
    conv = r.converged.copy()
    conv[:2] = False
    with pytest.raises(ValueError, match=r"label\(s\) \[0\]"):
        calibrate(RunResults(r.severity, r.x1_mean, r.params, conv))
    with pytest.raises(ValueError, match="need more runs"):
        x1_thresholds(r.severity[:3], r.x1_mean[:3])


def test_calibrate_cli_writes_a_ranges_file(tmp_path, capsys):
    out = tmp_path / "ranges.json"
    assert main(["calibrate", "--runs", "10", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "Table 3" in text and "f_c" in text
    assert Ranges.load(out).params["f_c"].direction == "rising"
