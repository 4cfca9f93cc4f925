"""Why a rig has its grade, in words: what each parameter is and how far it moved."""

from hydromon.engine.words import parameter_words, se_text, why_words
from monitor.ranges import Ranges


def test_the_parameters_that_carry_the_grade_in_words_against_the_rigs_baseline():
    h = {"grade": "deterioration", "params": {"K_sv": 1.4e-4, "f_c": 50.0, "C_ip": 3e-11},
         "param_grades": {"K_sv": "deterioration", "f_c": "deterioration", "C_ip": "health"}}
    assert why_words(h, Ranges.default()) == ["valve gain -44 % of its baseline", "Coulomb friction +900 % of its baseline"]
    assert why_words(dict(h, grade="health")) == [] and why_words(dict(h, grade="unknown")) == []
    assert why_words(h) == ["valve gain 0.00014 m/V", "Coulomb friction 50 N"]  # no ranges: values and units


def test_a_leakage_against_its_fault_threshold_and_an_unknown_standard_error():
    assert parameter_words("C_ip", 3.2e-10, threshold=1e-10) == "internal leakage 3.2x the fault threshold"
    assert parameter_words("C_ep", 5e-11, threshold=1e-10) == "external leakage below the fault threshold (50 % of it)"
    assert se_text(float("inf")) == "-" and se_text(None) == "-" and se_text(0.0123) == "0.0123"
