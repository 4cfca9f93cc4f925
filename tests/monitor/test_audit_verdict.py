"""The audit's verdict on hard records: an effect large enough to spoil the nominal fit, two
effects at once, and an effect outside the library (``unexplained``). Records from the sweep's
``hydromon.tools.audit_sweep._record``."""

from __future__ import annotations

import pytest

from hydromon.report.audit import summary, to_json, write_report
from hydromon.tools.audit_sweep import CLAIMS, _record
from monitor.audit import AuditOptions, audit
from plant_sim.params import EFFECT_NAMES

AIR_AT_FAULT = ("0.3 air fraction at fault-grade health (severity 0.9, paper-id) at realistic noise: the "
                "chamber equation's regressor noise (its residual at the true parameters 2.2e-8 (m^3/s)^2 "
                "against a left-side variance of 6.4e-11) hides the air; named sensor_delay; docs/limits.md")


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=AIR_AT_FAULT))
                                  if n == "entrained_air" else n for n in EFFECT_NAMES])
def test_an_effect_at_its_largest_magnitude_is_named(name):
    """The sweep's largest magnitude of each effect (large enough to make some nominal estimates
    impossible for several of them) is still named, one record each."""
    i = EFFECT_NAMES.index(name)
    s, cfg = _record("one", {name: CLAIMS[name][2]}, ("paper-id", "paper-var", "steps", "multisine")[i % 4],
                     0.1 + 0.2 * (i % 5), "realistic", 40 + i)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == name, (res.cause, res.note)
    assert SAID[name] in res.words, res.words


# what the verdict's words say for each effect (monitor.audit.verdict.cause_words)
SAID = {"stribeck_friction": "breakaway friction", "valve_saturation": "end stop", "valve_dead_band": "dead band",
        "supply_pressure_sag": "supply pressure sags", "entrained_air": "entrained air",
        "sensor_delay": "sample(s) late", "load_offset": "external force"}


def test_two_effects_at_once_are_both_named():
    s, cfg = _record("pair", {"entrained_air": 0.04, "load_offset": 800.0}, "steps", 0.3, "realistic", 6)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert set(res.causes) == {"entrained_air", "load_offset"}, (res.causes, res.note)
    assert abs(res.effect["load_offset"] - 800.0) < 200.0 and res.effect["air_fraction"] > 0.02, res.effect
    ext = to_json(res)["params_extended"]
    assert ext["load_offset"] == res.effect["load_offset"] and ext["air_fraction"] == res.effect["air_fraction"]


def test_a_second_effect_hidden_by_the_first_is_named():
    # alone, 4 % air scores nothing beside a 3-sample delay (the delay distorts its fit); fitted
    # together with the delay it earns its place by far
    s, cfg = _record("pair", {"sensor_delay": 3, "entrained_air": 0.04}, "paper-var", 0.5, "realistic", 100237)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.causes == ("sensor_delay", "entrained_air"), (res.causes, res.note)
    assert res.effect["sensor_delay"] == 3 and res.effect["air_fraction"] > 0.02, res.effect


@pytest.mark.parametrize("effects, profile, severity, seed", [
    ({"entrained_air": 0.04, "load_offset": 800.0}, "paper-id:offset=1.751,amplitude=1.005,freq=1.300", 0.746,
     12100228),
    ({"sensor_delay": 3, "entrained_air": 0.04}, "steps:low=1.297,high=2.356,period=1.548", 0.78, 12100238),
])
def test_a_pair_is_named_where_the_first_effect_raised_the_nominal_leakage(effects, profile, severity, seed):
    # the pair's fit put the external leakage a little below zero; simulated with the nominal
    # model's C_ep instead (raised by the unmodelled air), its free run simulated the record worse
    # than the first effect alone, and the second was not named
    s, cfg = _record("pair", effects, profile, severity, "realistic", seed)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert set(res.causes) == set(effects), (res.causes, res.note)
    assert res.effect["air_fraction"] > 0.02, res.effect


@pytest.mark.xfail(strict=True, reason="a clean healthy multisine record at realistic noise (held-out base 12300000, "
                   "the ladders' clean twin 115) is named 0.27 % of entrained air, confidently (score 0.44, free-run "
                   "gain 0.8 %); without noise it is named nothing; docs/limits.md")
def test_a_clean_healthy_multisine_record_at_realistic_noise_is_not_named_air():
    s, cfg = _record("clean", {}, "multisine:offset=1.924,amplitude=0.968,freqs=0.285/0.666/1.237/2.759/3.901", 0.131,
                     "realistic", 12310115)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == "none", (res.cause, res.note)


def test_an_effect_outside_the_library_is_unexplained_and_located():
    # a PI position loop the rig constants do not describe: the valve equation's drive is wrong
    s, cfg = _record("outside", {"pi_loop": 1}, "multisine", 0.5, "realistic", 11)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == "unexplained" and not res.causes and res.obeys, (res.cause, res.note)
    assert "the valve equation leaves" in res.note, res.note


def test_a_friction_that_grows_with_pressure_is_unexplained_and_a_breakaway_hump_is_still_named():
    # a piston seal friction 1e-4 m^2 x |p1 - p2|: the nearest candidates (a load offset, Coulomb
    # friction) soak up its mean; what follows the pressure is left, and no candidate has it
    s, cfg = _record("outside", {"seal_friction": 1}, "steps", 0.1, "realistic", 5)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == "unexplained" and not res.causes, (res.cause, res.note)
    assert "force equation" in res.note and "grows with pressure" in res.note, res.note
    # a genuine friction effect of the library on the same input leaves no such structure
    s, cfg = _record("one", {"stribeck_friction": 600.0}, "steps", 0.5, "realistic", 17)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == "stribeck_friction", (res.cause, res.note)


def test_a_seal_friction_on_the_papers_sine_is_unexplained_not_a_load_offset():
    # on the paper's sine the seal's friction is larger moving one way than the other, so a load
    # offset takes its mean (it scored 1.5 there); what is left follows sign(v) |p1 - p2|, which
    # two columns sign(v) x3, sign(v) x4 (nearly collinear with sign(v): x3 + x4 stays near the
    # supply) did not resolve on the held-out part
    s, cfg = _record("outside", {"seal_friction": 1}, "paper-id", 0.7, "realistic", 23)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == "unexplained" and not res.causes, (res.cause, res.note)
    assert "grows with pressure" in res.note, res.note


def test_a_stribeck_hump_that_cannot_be_excluded_comes_with_the_records_sliding_speeds():
    # the paper's sine at fault-grade health slides slower than the hump fades: the note says so
    import re

    s, cfg = _record("clean", {}, "paper-id", 0.9, "realistic", 30)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == "none", (res.cause, res.note)
    m = re.search(r"slides at ([0-9.]+) mm/s at the median and faster than 20 mm/s in ([0-9]+) %", res.note)
    assert m and "cannot be excluded: stribeck_friction" in res.note, res.note
    assert float(m.group(1)) < 5.0 and int(m.group(2)) < 10, res.note


def test_a_residual_share_that_follows_no_measured_signal_is_not_called_structure():
    from monitor.audit.decide import STRUCTURE, STRUCTURE_R, _structure_words

    share = 1.5 * STRUCTURE["chamber"]
    assert _structure_words({"chamber": {"share": share, "like": "spool position", "r": 0.5 * STRUCTURE_R}}) == ""
    said = _structure_words({"chamber": {"share": share, "like": "spool position", "r": -2 * STRUCTURE_R}})
    assert "chamber equation" in said and "spool position" in said
    assert _structure_words({"chamber": {"share": 0.5 * STRUCTURE["chamber"], "like": "velocity", "r": 0.9}}) == ""


def test_a_residual_larger_than_its_equation_s_variance_is_said_in_times_not_percent():
    """Entrained air at realistic noise in the fault band leaves the nominal chamber equation a
    residual beyond the sensor noise 8-54 times the variance of its left side: "4881 % of its
    variance unexplained" reads as nonsense; a multiple with what it means does not."""
    from monitor.audit.decide import _structure_words

    said = _structure_words({"chamber": {"share": 48.81, "like": "spool position", "r": -0.33}})
    assert said == ("the chamber equation leaves a held-out residual 48.8 times the variance of its left side "
                    "(beyond the sensor noise): the model predicts it worse than the left side's mean would, "
                    "correlated with spool position (r = -0.33)"), said
    assert "%" not in said
    said = _structure_words({"force": {"share": 0.45, "like": "velocity", "r": -0.95}})
    assert said == "the force equation leaves 45 % of its variance unexplained, correlated with velocity (r = -0.95)"


def test_an_extension_whose_free_run_errs_far_more_than_the_nominal_is_not_named_and_a_genuine_sag_still_is():
    from monitor.audit.decide import GAIN_FLOOR

    # a clean multisine record at stress noise: a supply sag lowers the chamber residual only
    # through its own larger predicted noise share, and its model does not simulate the record
    s, cfg = _record("clean", {}, "multisine", 0.7, "stress", 100224)
    res = audit(s, cfg, AuditOptions(free_run=False))
    sag = next(c for c in res.candidates if c.name == "supply_pressure_sag")
    assert sag.score > 0.15 and sag.gain < GAIN_FLOOR, (sag.score, sag.gain)
    assert res.cause == "none", (res.cause, res.note)
    # a genuine sag at its realistic-noise limit wins partly the same way, and simulates better
    s, cfg = _record("one", {"supply_pressure_sag": 1e9}, "paper-var", 0.3, "realistic", 100081)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == "supply_pressure_sag" and res.best.gain > 0, (res.cause, res.note)


def test_a_load_offset_at_fault_grade_health_is_named_though_the_mass_is_not_identified():
    # the piston barely accelerates: the mass is estimated <= 0 by the nominal fit and by the
    # offset's; the free run held it at a 1 kg floor, where 5700 N s/m of damping is too stiff for
    # its 1 ms step, diverged, and the offset (held-out score 16.6) was passed over
    s, cfg = _record("one", {"load_offset": 1600.0}, "paper-var:period=11.346", 0.966, "realistic", 8100154)
    res = audit(s, cfg, AuditOptions(free_run=False))
    off = next(c for c in res.candidates if c.name == "load_offset")
    assert off.params["m"] <= 0 and off.gain > 0.5, (off.params["m"], off.gain)
    assert res.causes == ("load_offset",), (res.causes, res.note)


def test_a_breakaway_hump_is_more_than_0_n_fading_over_1_to_40_mm_s():
    from monitor.audit.candidates import StribeckFriction

    hump = StribeckFriction()
    assert hump.plausible({"stribeck_F_s": 80.0, "stribeck_v_s": 0.01})
    for f_s, v_s in ((0.0, 0.01), (80.0, 1e-13), (80.0, 0.05), (-5.0, 0.01)):
        assert not hump.plausible({"stribeck_F_s": f_s, "stribeck_v_s": v_s}), (f_s, v_s)


def test_a_stribeck_friction_of_0_n_is_not_named(tmp_path):
    # 4 % air and an 800 N load offset on paper-var at fault-grade health: the rest rows' static
    # level takes what the offset holds (score 11.9), and the output-error refinement walks the
    # hump to 0 N over 0 mm/s; it was named beside the air
    s, cfg = _record("pair", {"entrained_air": 0.04, "load_offset": 800.0}, "paper-var:period=7.253", 0.927,
                     "realistic", 12100229)
    res = audit(s, cfg, AuditOptions(free_run=False))
    hump = next(c for c in res.candidates if c.name == "stribeck_friction")
    assert hump.score > 0.3 and hump.effect["stribeck_F_s"] < 1.0 and not hump.plausible, (hump.score, hump.effect)
    assert "stribeck_friction" not in res.causes and res.cause != "stribeck_friction", (res.causes, res.note)
    # every sliding row of the force equation runs one way: a constant force is Coulomb friction
    # there, and the load offset cannot be fitted; said, not dropped in silence
    assert "load_offset" not in {c.name for c in res.candidates} and "singular" in res.unfitted["load_offset"]
    assert to_json(res)["unfitted"] == res.unfitted and "load_offset" in summary(res)
    assert "Not fitted: load_offset: its extended equations are singular" in write_report(res, tmp_path).read_text()


@pytest.mark.parametrize("profile, severity, seed, named", [
    ("steps:low=1.419,high=2.256,period=2.747", 0.368, 11710151, "supply_pressure_sag"),
    ("steps:low=1.507,high=2.546,period=2.563", 0.565, 11710152, "supply_pressure_sag"),
])
def test_a_negative_air_fraction_is_no_air(profile, severity, seed, named):
    # a 3.2e10 Pa/(m^3/s) supply sag on steps at realistic noise (tuning ladder): the chamber
    # equation fitted a negative air fraction (oil stiffer at low pressure), which scored 0.40
    # and named "entrained air, 0 %" on the first record, and tied with the sag on the second;
    # the sag itself is named on both since its search reaches beyond 2e10
    from monitor.audit.candidates import EntrainedAir

    assert not EntrainedAir().admissible({"chamber": {"air_fraction": -1e-4}})
    s, cfg = _record("one", {"supply_pressure_sag": 3.2e10}, profile, severity, "realistic", seed)
    res = audit(s, cfg, AuditOptions(free_run=False))
    air = next(c for c in res.candidates if c.name == "entrained_air")
    assert air.score <= 0.0 and air.effect["air_fraction"] == 0.0, (air.score, air.effect)
    assert res.cause == named and res.confident, (res.cause, res.note)


def test_a_hump_that_the_nominal_twin_shows_as_well_is_not_named():
    # a clean noise-free steps record in the fault band: the piston creeps at 1.6 mm/s between
    # sticks and Stribeck friction scores 0.99 on the equations; the nominal model's own twin
    # (its free run, no effect in it) scores the hump as high, so the equations' hump is what
    # they make of this creeping motion (its output-error refinement spread it over 123 mm/s)
    s, cfg = _record("clean", {}, "steps:low=1.566,high=2.452,period=1.823", 0.844, "none", 8220071)
    res = audit(s, cfg, AuditOptions(free_run=False))
    hump = next(c for c in res.candidates if c.name == "stribeck_friction")
    assert hump.score + hump.twin > 0.3 and hump.score <= 0.3, (hump.score, hump.twin)
    assert res.cause == "none", (res.cause, res.note)
    assert "stribeck_friction scores" in res.note and "nominal model's twin" in res.note, res.note


def test_a_tie_that_the_nominal_twin_shows_as_well_names_nothing():
    # a clean noise-free paper-var record in the fault band: a supply sag of about 1.3e8 and
    # entrained air tied at 0.21 on the equations, neither simulating the held-out part better
    # than the nominal model; the nominal model's twin scores the sag at 0.19 as well
    s, cfg = _record("clean", {}, "paper-var:period=6.674", 0.865, "none", 8220046)
    res = audit(s, cfg, AuditOptions(free_run=False))
    sag = next(c for c in res.candidates if c.name == "supply_pressure_sag")
    assert sag.score + sag.twin > 0.15 and sag.score <= 0.15, (sag.score, sag.twin)
    assert res.cause == "none", (res.cause, res.note)


def test_air_at_fault_grade_health_whose_noise_rivals_its_signal_is_named():
    """4 % air on a paper-id record at fault-grade health and realistic noise (tuning base
    10900000, --ladder entrained_air, record 84): the air column and the 1/beta_e column carry
    the same pressure-rate noise, which held 1.07 times the data's energy in one direction of
    the chamber equation; compensated in full, the air fit was noise and the record came out
    ``unexplained``."""
    s, cfg = _record("one", {"entrained_air": 0.04}, "paper-id:offset=2.057,amplitude=1.060,freq=1.034", 0.976,
                     "realistic", 10910084)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.causes == ("entrained_air",), (res.causes, res.note)


def test_a_second_cause_that_does_not_simulate_the_record_better_is_not_named():
    """4 % air on a paper-id record at fault-grade health and realistic noise (tuning base
    10900000, main sweep, record 99): a sensor delay fitted beside the air beat the air alone
    on the held-out equations, but the two simulated the held-out part no better than the air
    alone, so only the air is named."""
    s, cfg = _record("one", {"entrained_air": 0.04}, "paper-id:offset=1.924,amplitude=0.992,freq=0.841", 0.855,
                     "realistic", 10900099)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.causes == ("entrained_air",), (res.causes, res.note)


def test_a_large_supply_sag_is_searched_beyond_2e10():
    # a 3.2e10 Pa/(m^3/s) sag at realistic noise on paper-var (tuning sag ladder, record 145): a
    # search ending at 2e10 was pinned at its edge (refined to 3.05e10) and scored 0.13, below the
    # threshold; the search now reaches 1.4e11 and refines it to 3.5e10 (score 0.28)
    from monitor.audit.candidates import SupplyPressureSag

    assert max(SupplyPressureSag().grid(None)) >= 1.4e11 - 1.0
    s, cfg = _record("one", {"supply_pressure_sag": 3.2e10}, "paper-var:period=13.727", 0.033, "realistic", 11710145)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.causes == ("supply_pressure_sag",), (res.causes, res.note)
    sag = next(c for c in res.candidates if c.name == "supply_pressure_sag")
    assert 3.05e10 < sag.value < 1.4e11 and sag.score > 0.15 and sag.gain > 0.3, (sag.value, sag.score, sag.gain)


def test_a_sag_whose_orifice_coefficient_does_not_reproduce_itself_is_refused():
    # a 1.6e10 Pa/(m^3/s) sag at realistic noise on paper-var (tuning sag ladder, record 127):
    # from 2.1e10 up no orifice coefficient reproduces itself (the line cannot pass the record's
    # flows), yet the training equations preferred 5.3e10, whose free run erred 13 times as much as
    # the nominal model's; such values are refused and the search keeps the consistent one
    s, cfg = _record("one", {"supply_pressure_sag": 1.6e10}, "paper-var:period=9.982", 0.432, "realistic", 11710127)
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.causes == ("supply_pressure_sag",), (res.causes, res.note)
    sag = next(c for c in res.candidates if c.name == "supply_pressure_sag")
    assert 1.2e10 < sag.value < 2.1e10 and sag.gain > 0.5, (sag.value, sag.gain)


def test_pressures_logged_as_gauge_read_as_a_load_offset_and_the_words_say_so():
    """Both pressures 1 bar low (gauge logged for absolute) add -(A1 - A2) x 1 bar to the force
    balance, as a constant load would: named a load offset, and the words say a pressure sensor's
    zero offset reads the same way."""
    s, cfg = _record("clean", {}, "paper-var", 0.3, "realistic", 5)
    s = s.copy()
    s[:, 2:4] -= 1e5
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == "load_offset", (res.cause, res.note)
    assert abs(res.effect["load_offset"] + (cfg.A1 - cfg.A2) * 1e5) < 0.25 * (cfg.A1 - cfg.A2) * 1e5, res.effect
    assert "or a pressure sensor's zero offset" in res.words, res.words


@pytest.mark.parametrize("what, mutate", [("ug ten times too large", lambda ug: 10.0 * ug),
                                          ("ug 1 V off", lambda ug: ug + 1.0)])
def test_a_command_in_other_units_is_unexplained_in_the_valve_equation_with_where_to_look(what, mutate):
    """A command logged in other units or with an offset passes the readings' checks (the config
    gives ug no span) and fits no candidate: the valve equation keeps the residual, and the words
    say what that equation holds, the command first, so a person looks at the logging before the
    valve."""
    s, cfg = _record("clean", {}, "paper-var", 0.3, "realistic", 5)
    s = s.copy()
    s[:, 0] = mutate(s[:, 0])
    res = audit(s, cfg, AuditOptions(free_run=False))
    assert res.cause == "unexplained" and "the valve equation leaves" in res.note, (what, res.note)
    assert "Where to look: the valve equation relates x5 to the valve input K_p (ug - K_f x1): a command logged " \
           "in other units or with an offset" in res.note, res.note
    s0, _ = _record("clean", {}, "paper-var", 0.3, "realistic", 5)
    assert audit(s0, cfg, AuditOptions(free_run=False)).cause == "none"  # the record as logged right
