"""Health relative to a rig's own baseline: the reference ranges carried over by a rig's healthy
values, exactly unchanged on the reference rig; ranges apply only to the rig they were made for."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hydromon.contract import RigConfig
from monitor.ranges import Ranges
from monitor.relative import REFERENCE_HEALTHY, relative_factor, relative_ranges
from plant_sim.degradation import degrade, degrade_relative, leak_scale
from plant_sim.params import PlantParams


@pytest.mark.parametrize("reference", [Ranges.default(), Ranges.paper()], ids=["default", "paper"])
def test_the_reference_rig_gets_the_reference_ranges_bit_for_bit(reference):
    ranges, left_out = relative_ranges(REFERENCE_HEALTHY, RigConfig(), reference)
    assert left_out == {}
    assert ranges.params == reference.params  # exact: every factor is 1.0
    assert ranges.made_for(RigConfig()) is None


@settings(max_examples=60, deadline=None)
@given(k=st.floats(0.05, 20.0), name=st.sampled_from(["K_sv", "f_c", "B_fv"]))
def test_a_parameters_bands_scale_with_its_own_baseline_only(k, name):
    # (the leakage thresholds scale with the valve's gain too: a valve passing more flow makes a
    # larger leakage harmless)
    base = dict(REFERENCE_HEALTHY)
    base[name] *= k
    ranges, _ = relative_ranges(base, RigConfig())
    ref = Ranges.default()
    for other, pr in ranges.params.items():
        scaled = other == name or name == "K_sv" and other in ("C_ip", "C_ep")
        want = np.array(ref.params[other].edge_array()) * (k if scaled else 1.0)
        np.testing.assert_allclose(pr.edge_array(), want, rtol=1e-12)


def test_a_leakage_threshold_scales_with_the_valve_flow_against_the_supply():
    # twice the orifice coefficient and the valve gain, four times the supply: the valve's flow
    # per volt grows 2 * 2 * 2 = 8 times, the leakage flow per m^3/(s Pa) 4 times: threshold x2
    base = dict(REFERENCE_HEALTHY, CdW_sqrt_rho=2 * REFERENCE_HEALTHY["CdW_sqrt_rho"], K_sv=2 * REFERENCE_HEALTHY["K_sv"])
    cfg = RigConfig(p_s=4 * RigConfig().p_s)
    assert relative_factor("C_ip", base, cfg) == pytest.approx(2.0, rel=1e-12)
    ranges, _ = relative_ranges(base, cfg)
    assert ranges.params["C_ep"].fault_threshold == pytest.approx(2 * Ranges.default().params["C_ep"].fault_threshold)
    assert leak_scale(REFERENCE_HEALTHY["CdW_sqrt_rho"], REFERENCE_HEALTHY["K_sv"], RigConfig().p_s) == 1.0


def test_a_baseline_that_cannot_carry_bands_leaves_its_parameter_out():
    base = dict(REFERENCE_HEALTHY, f_c=-0.5)
    ranges, left_out = relative_ranges(base, RigConfig())
    assert "f_c" not in ranges.params and "f_c" in left_out and "-0.5" in left_out["f_c"]
    assert math.isnan(relative_factor("C_ip", dict(base, K_sv=0.0), RigConfig()))


def test_ranges_apply_only_to_the_rig_constants_they_were_made_for():
    ranges = Ranges.default()
    assert ranges.made_for(None) is None and ranges.made_for(RigConfig()) is None
    assert ranges.made_for(RigConfig(p_s=12e6 * (1 + 1e-7))) is None  # a decimal round trip
    why = ranges.made_for(RigConfig(A1=0.012, p_s=16e6))
    assert "A1 0.012 (ranges made for 0.008)" in why and "p_s 1.6e+07 (ranges made for 1.2e+07)" in why
    assert ranges.made_for(RigConfig(x1_span=0.5)) is None  # a sensor span does not identify anything
    assert Ranges(params=ranges.params).made_for(RigConfig()) == "the ranges name no rig constants they were made for"


@pytest.mark.parametrize("severity", [0.0, 0.1, 0.35, 0.55, 0.75, 0.85, 1.0])
def test_the_reference_plant_degrades_relative_to_itself_as_it_does_in_absolute_terms(severity):
    a, b = degrade(severity).identified(), degrade_relative(severity, PlantParams()).identified()
    for k in a:
        assert b[k] == pytest.approx(a[k], rel=1e-12, abs=1e-30), k


def test_a_larger_rig_degrades_by_the_same_ratios():
    base = PlantParams(K_sv=1.4e-4, f_c=12.0, B=12000.0, f_v=50.0)
    for s in (0.3, 0.7):
        ref, big = degrade(s).identified(), degrade_relative(s, base).identified()
        for k in ("K_sv", "f_c", "CdW_sqrt_rho"):
            assert big[k] / base.identified()[k] == pytest.approx(ref[k] / PlantParams().identified()[k], rel=1e-12)
        assert big["B_fv"] / (base.B + base.f_v) == pytest.approx(ref["B_fv"] / 6025.0, rel=1e-12)
