"""Commissioning a rig that is not the reference rig: its baseline, its own ranges from a record
of it in good condition, the rig then graded right at every grade; refusals of records that
cannot commission; labelled calibration from a rig's own records."""

import numpy as np
import pytest

from hydromon.contract import GRADES, PARAM_NAMES, RigConfig
from monitor.calibrate import calibrate_labelled
from monitor.commission import MIN_SECONDS, commission
from monitor.pipeline import Pipeline
from monitor.ranges import Ranges
from plant_sim.degradation import degrade_relative
from plant_sim.noise import noise_model
from plant_sim.params import PlantParams
from plant_sim.profiles import PaperVariable, Steps
from plant_sim.simulate import simulate

CFG = RigConfig(A1=0.012, A2=0.006, V10=0.15, V20=0.12, p_s=16e6, F_L=6000.0)
HEALTHY = PlantParams(m=300.0, B=12000.0, K_sv=1.4e-4, f_c=12.0, f_v=50.0)
NOISE = noise_model("realistic", CFG)


@pytest.fixture(scope="module")
def commissioned():
    rec = simulate(PaperVariable(), 30.0, params=HEALTHY, config=CFG, noise=NOISE, seed=1)
    return commission(rec.samples, CFG, runs=20, seed=100, made_on="test", created="2026-01-01T00:00:00Z")


def test_the_baseline_is_the_rigs_own_and_the_ranges_are_made_for_it(commissioned):
    c = commissioned
    assert c.ranges.rig == CFG and c.ranges.made_for(CFG) is None and c.ranges.made_for(RigConfig()) is not None
    assert c.ranges.baseline["K_sv"].value == pytest.approx(1.4e-4, rel=5e-3)
    assert set(c.ranges.baseline) == set(PARAM_NAMES)
    assert {"K_sv", "C_ip", "C_ep"} <= set(c.ranges.params)
    # the bands are the rig's, not the reference rig's: a valve gain of 1.4e-4 m/V is health here and
    ref = Ranges.default().params["K_sv"].edges
    assert ref[3] < 1.4e-4 <= ref[2] and c.ranges.params["K_sv"].edges[0] < 1.4e-4  # deterioration there
    assert c.noise["x3"] == pytest.approx(5e3, rel=0.1)
    assert Ranges.model_validate_json(c.ranges.model_dump_json()) == c.ranges  # the file round-trips


@pytest.mark.parametrize("severity", [0.1, 0.3, 0.5, 0.7, 0.9])
def test_the_commissioned_rig_is_graded_right_at_every_grade(commissioned, severity):
    plant = degrade_relative(severity, HEALTHY, CFG)
    rec = simulate(PaperVariable(), 30.0, params=plant, config=CFG, noise=NOISE, seed=7)
    _, a = Pipeline(config=CFG, ranges=commissioned.ranges).run(rec.samples)
    assert a.grade == GRADES[int(severity / 0.2)], a.param_levels


def test_a_record_too_short_or_still_is_refused_naming_why():
    short = simulate(PaperVariable(), MIN_SECONDS - 1, params=HEALTHY, config=CFG, seed=1)
    with pytest.raises(ValueError, match="too short: give at least 10 s"):
        commission(short.samples, CFG, runs=0)
    still = simulate(Steps(low=2.0, high=2.0), 40.0, params=HEALTHY, config=CFG, noise=NOISE, seed=1)
    with pytest.raises(ValueError, match="did not converge|pins no graded parameter|does not pin"):
        commission(still.samples[2000:], CFG, runs=0)


@pytest.mark.parametrize("column, factor, said", [(5, 100.0, "x5 reaches"), (3, -1.0, "x3 falls to -")])
def test_a_record_in_other_units_is_refused_before_ranges_are_made_around_them(column, factor, said):
    """A spool in 0.01 mm or a pressure with its sign turned gives plausible estimates with the
    units in them: ranges made around those would grade the rig's right readings as a fault."""
    rec = simulate(PaperVariable(), 12.0, params=HEALTHY, config=CFG, noise=NOISE, seed=1)
    s = rec.samples.copy()
    s[:, column - 1] *= factor
    with pytest.raises(ValueError, match=f"^the record's readings cannot be in the rig config's units: {said}"):
        commission(s, CFG, runs=0)


def test_a_parameter_the_record_cannot_pin_is_left_ungraded_with_the_input_that_would(commissioned):
    # B + f_v's bands are 0.8 % wide; 30 s at realistic noise does not pin its baseline that well
    c = commissioned
    assert "B_fv" in c.ungraded and "faster piston motion" in c.ungraded["B_fv"]
    assert "B_fv" not in c.ranges.params and any(w.startswith("B_fv left ungraded") for w in c.warnings)


def test_labelled_records_give_the_rigs_ranges_and_a_commissioned_file_fills_missing_grades(commissioned):
    rows, labels = [], []
    for g, s in enumerate((0.1, 0.3, 0.5, 0.7, 0.9)):
        for seed in (21, 22):
            plant = degrade_relative(s, HEALTHY, CFG)
            rec = simulate(PaperVariable(), 20.0, params=plant, config=CFG, noise=NOISE, seed=seed)
            a = Pipeline(config=CFG, ranges=None).run(rec.samples)[1]
            rows.append([a.params[k] for k in PARAM_NAMES])
            labels.append(g)
    rows, labels = np.array(rows), np.array(labels)
    ranges = calibrate_labelled(rows, labels, CFG)
    assert ranges.made_for(CFG) is None
    lo, hi = commissioned.relative.params["K_sv"].edges, ranges.params["K_sv"].edges
    np.testing.assert_allclose(hi, lo, rtol=0.05)  # the records' edges sit near the relative bands
    partial = labels <= 2  # only health, sub-health and average recorded
    with pytest.raises(ValueError, match="no record graded deterioration, fault"):
        calibrate_labelled(rows[partial], labels[partial], CFG)
    filled = calibrate_labelled(rows[partial], labels[partial], CFG, commissioned=commissioned.ranges)
    assert filled.params["K_sv"].edges[2:] == commissioned.ranges.params["K_sv"].edges[2:]
    assert filled.params["C_ip"] == commissioned.ranges.params["C_ip"]
    # labels in reverse order (4 the healthy records) would turn every direction: each parameter
    # then moves against wear, and is left out saying so
    with pytest.raises(ValueError, match="no graded parameter could be calibrated: .*are the labels in reverse order"):
        calibrate_labelled(rows, 4 - labels, CFG)
    assert not calibrate_labelled(rows, labels, CFG).ungraded.keys() & {"K_sv", "C_ip", "C_ep"}
    # a threshold the records cannot place (no fault record) keeps the commissioned one and its
    # direction, whichever way the records' noise leans
    two, two_labels = rows[labels <= 1].copy(), labels[labels <= 1]
    c_ip = PARAM_NAMES.index("C_ip")
    two[two_labels == 1, c_ip] = 0.999 * np.median(two[two_labels == 0, c_ip])  # noise leaning the other way
    got = calibrate_labelled(two, two_labels, CFG, commissioned=commissioned.ranges)
    assert got.params["C_ip"] == commissioned.ranges.params["C_ip"], got.ungraded
