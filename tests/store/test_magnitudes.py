"""Magnitudes with units: one parser for options and files, which refuses a number in the wrong
unit (a dead band of 2.5 m) and takes it with its unit (2.5um)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hydromon.cli.main import main
from hydromon.store import quantities
from hydromon.store.fleetfile import RigSpec, load_fleet, parse_controller, parse_effect
from hydromon.store.magnitudes import MagnitudeError, parse, parse_unit

DOCS = Path(__file__).resolve().parents[2] / "docs"


@pytest.mark.parametrize("text, quantity, si", [
    ("2.5um", quantities.EFFECTS["valve_dead_band"], 2.5e-6),
    ("2.5 µm", quantities.EFFECTS["valve_dead_band"], 2.5e-6),
    ("0.3mm", quantities.EFFECTS["valve_saturation"], 3e-4),
    ("40N", quantities.EFFECTS["stribeck_friction"], 40.0),
    ("-0.2kN", quantities.EFFECTS["load_offset"], -200.0),
    ("0.5%", quantities.EFFECTS["entrained_air"], 0.005),
    ("3 bar/(L/min)", quantities.EFFECTS["supply_pressure_sag"], 1.8e10),
    ("2samples", quantities.EFFECTS["sensor_delay"], 2.0),
    ("12MPa", quantities.CONFIG["p_s"], 12e6),
    ("120 bar", quantities.CONFIG["p_s"], 12e6),
    ("80cm^2", quantities.CONFIG["A1"], 0.008),
    ("110L", quantities.CONFIG["V10"], 0.11),
    ("2.5e-4m/V", quantities.PLANT["K_sv"], 2.5e-4),
    ("0.25mm/V", quantities.PLANT["K_sv"], 2.5e-4),
    ("3e-11m^3/(s Pa)", quantities.PLANT["C_ip"], 3e-11),
    ("0.18 L/(min bar)", quantities.PLANT["C_ip"], 3e-11),
    ("16Hz", quantities.PLANT["omega_sv"], 100.53096491487338),  # Hz counts cycles: 2 pi rad each
    ("6000", quantities.PLANT["B"], 6000.0),  # a bare number is SI
    (2.5e-6, quantities.EFFECTS["valve_dead_band"], 2.5e-6),
    ("5/s", quantities.CONTROLLER["K_i"], 5.0),
    ("2min", quantities.MEMORY, 120.0),
])
def test_a_magnitude_is_read_in_its_unit(text, quantity, si):
    assert parse(text, quantity, "x") == pytest.approx(si, rel=1e-12)


@pytest.mark.parametrize("text, quantity, message", [
    ("2.5", quantities.EFFECTS["valve_dead_band"], "dead 2.5 m is outside 0..1 mm: give a unit, e.g. 2.5um"),
    (2.5, quantities.EFFECTS["valve_dead_band"], "dead 2.5 m is outside 0..1 mm: give a unit, e.g. 2.5um"),
    ("0.01", quantities.EFFECTS["valve_saturation"], "dead 0.01 m is outside 0..1 mm: give a unit, e.g. 0.3mm"),
    ("2mm", quantities.EFFECTS["valve_dead_band"], "dead 2 mm is outside 0..1 mm: e.g. 2.5um"),
    ("40N", quantities.EFFECTS["valve_dead_band"], "dead '40N': N is not a unit of m"),
    ("12", quantities.CONFIG["p_s"], "dead 12 Pa is outside 0.1..100 MPa: give a unit, e.g. 12MPa"),
    ("5 furlong", quantities.EFFECTS["valve_dead_band"], "unknown unit 'furlong'"),
    ("lots", quantities.EFFECTS["valve_dead_band"], "'lots' is not a number with a unit"),
    ("1.5", quantities.EFFECTS["sensor_delay"], "whole number of samples"),
    (True, quantities.EFFECTS["load_offset"], "not a magnitude"),
    ("nan", quantities.EFFECTS["load_offset"], "not a number with a unit"),
])
def test_a_magnitude_in_the_wrong_unit_is_refused_in_one_line(text, quantity, message):
    with pytest.raises(MagnitudeError, match=message.replace("(", r"\(").replace(")", r"\)")) as exc:
        parse(text, quantity, "dead")
    assert "\n" not in str(exc.value)


def test_units_compose():
    assert parse_unit("N s/m") == parse_unit("kg/s")
    assert parse_unit("m^3/(s Pa)")[1] == parse_unit("m^4 s/kg")[1]
    with pytest.raises(MagnitudeError):
        parse_unit("m/(s")


# -- every place a magnitude is taken -------------------------------------------------------------

def test_sim_effect_refuses_a_dead_band_of_metres_and_takes_micrometres(tmp_path, capsys):
    out = tmp_path / "db.csv"
    base = ["sim", "--to-csv", str(out), "--duration", "0.5", "--rig", "table4-g2"]
    assert main([*base, "--effect", "valve_dead_band=2.5"]) == 2
    assert capsys.readouterr().err.strip() == ("hydromon sim: error: valve_dead_band 2.5 m is outside 0..1 mm: "
                                               "give a unit, e.g. 2.5um")
    assert not out.exists()
    assert main([*base, "--effect", "valve_dead_band=2.5um"]) == 0
    assert out.exists()
    assert parse_effect("valve_dead_band=2.5um") == ("valve_dead_band", 2.5e-6)


def _fleet(tmp_path, body: str) -> Path:
    p = tmp_path / "fleet.toml"
    p.write_text('[[rigs]]\nid = "a"\n' + body)
    return p


@pytest.mark.parametrize("body", [
    "effects = { valve_dead_band = 2.5 }",
    'effects = { valve_dead_band = "2.5" }',
    "params = { K_sv = 2.5 }",
    "base = { K_sv = 2.5 }",
    "config = { x5_span = 2.5 }",
])
def test_fleet_files_refuse_metres_for_a_spool_and_take_units(tmp_path, body):
    with pytest.raises(ValueError, match=r"2\.5 m(/V)? is outside .*: give a unit"):
        load_fleet(_fleet(tmp_path, body))
    fixed = body.replace('"2.5"', '"2.5um"').replace("2.5 }", '"2.5um" }').replace("K_sv = \"2.5um\"",
                                                                                'K_sv = "2.5e-4m/V"')
    load_fleet(_fleet(tmp_path, fixed))


def test_a_fleet_with_units_is_the_fleet_in_si(tmp_path):
    spec = load_fleet(_fleet(tmp_path, 'effects = { valve_dead_band = "2.5um", load_offset = "0.2kN" }\n'
                                       'params = { f_c = "30N" }\nconfig = { p_s = "120bar" }\n'
                                       'controller = "pi:ki=5/s,kff=20ms"\n[config]\nA1 = "80cm^2"\n'))
    (rig,) = spec.rigs
    assert rig.effects == {"valve_dead_band": 2.5e-6, "load_offset": 200.0}
    assert rig.params == {"f_c": 30.0} and rig.config == {"p_s": 12e6} and spec.config.A1 == pytest.approx(0.008)
    assert rig.controller_model().K_ff == pytest.approx(0.02) and rig.controller_model().K_i == 5.0
    assert RigSpec(**rig.model_dump()) == rig  # written back in SI, read again the same


def test_the_controller_gains_take_units_and_refuse_nonsense():
    assert parse_controller("pi:kff=20ms").K_ff == pytest.approx(0.02)
    with pytest.raises(ValueError, match="kff '20V'"):
        parse_controller("pi:kff=20V")


def test_a_config_file_takes_units(tmp_path, capsys):
    csv = tmp_path / "rig.csv"
    csv.write_text("t,ug,x1,x3,x4,x5\n0,2,0,6e6,4e6,0\n")
    conf = tmp_path / "rig.json"
    conf.write_text(json.dumps({"x5_span": 2.5}))
    assert main(["evaluate", str(csv), "--config", str(conf)]) == 2
    assert "x5_span 2.5 m is outside 0.001..100 mm: give a unit, e.g. 1mm" in capsys.readouterr().err
    from hydromon.cli.rigconfig import config_from_args

    conf.write_text(json.dumps({"p_s": "12MPa", "x5_span": "2.5mm", "sample_rate": 200}))
    c = config_from_args(type("A", (), {"config": str(conf)})())
    assert (c.p_s, c.x5_span, c.sample_rate) == (12e6, 2.5e-3, 200.0)


def test_docs_and_help_state_the_same_units_and_ranges():
    text = (DOCS / "operations.md").read_text()
    for table in (quantities.EFFECTS, quantities.PLANT, quantities.CONFIG):
        for name, unit, rng, example in quantities.unit_table(table):
            assert f"| `{name}` | {unit} | {rng} | `{example}` |" in text, name
