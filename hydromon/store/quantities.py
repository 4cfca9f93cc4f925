"""Every physical magnitude hydromon takes from a person, with its SI unit and its sensible range
(:class:`hydromon.store.magnitudes.Quantity`): the effects of ``sim --effect`` and fleet files,
the plant parameters (``params``, ``base``), the rig constants (``config``, ``--config``), the
controller's gains and the estimators' memory.

The ranges are wide enough for any servo cylinder from a test bench to a rolling mill, and
narrow enough to catch a number in the wrong unit: a valve's spool moves about a millimetre,
so a dead band of 2.5 (metres) is refused with the hint to write ``2.5um``.
"""

from __future__ import annotations

import math

from hydromon.store.magnitudes import Quantity, parse

__all__ = ["EFFECTS", "PLANT", "CONFIG", "CONTROLLER", "MEMORY", "convert", "unit_table"]

Q = Quantity

EFFECTS = {
    "stribeck_friction": Q("N", 0.0, 1e5, "kN", "40N"),
    "valve_saturation": Q("m", 0.0, 1e-3, "mm", "0.3mm", lo_open=True),
    "valve_dead_band": Q("m", 0.0, 1e-3, "mm", "2.5um"),
    "supply_pressure_sag": Q("Pa/(m^3/s)", 0.0, 1e11, "Pa/(m^3/s)", "2e9Pa/(m^3/s)"),
    "entrained_air": Q("", 0.0, 0.2, "", "0.5%"),
    "sensor_delay": Q("samples", 0.0, 1000.0, "samples", "2samples", integer=True),
    "load_offset": Q("N", -1e6, 1e6, "kN", "200N"),
}
"""Effect name -> its magnitude (``hydromon.store.fleetfile.EFFECT_FIELDS`` names the field)."""

PLANT = {
    "m": Q("kg", 0.0, 1e5, "kg", "120kg", lo_open=True),
    "B": Q("N s/m", 0.0, 1e7, "N s/m", "6000N s/m"),
    "K_t": Q("N/m", 0.0, 1e10, "N/m", "1e6N/m"),
    "beta_e": Q("Pa", 1e7, 3e9, "MPa", "700MPa"),
    "rho": Q("kg/m^3", 500.0, 1500.0, "kg/m^3", "880kg/m^3"),
    "C_d": Q("", 0.0, 1.0, "", "0.6", lo_open=True),
    "W": Q("m", 0.0, 1.0, "m", "30mm", lo_open=True),
    "C_ip": Q("m^3/(s Pa)", 0.0, 1e-8, "m^3/(s Pa)", "3e-11m^3/(s Pa)"),
    "C_ep": Q("m^3/(s Pa)", 0.0, 1e-8, "m^3/(s Pa)", "3e-11m^3/(s Pa)"),
    "K_sv": Q("m/V", 0.0, 1e-2, "mm/V", "2.5e-4m/V", lo_open=True),
    "omega_sv": Q("rad/s", 0.0, 1e5, "rad/s", "100rad/s", lo_open=True),
    "zeta_sv": Q("", 0.0, 10.0, "", "0.5", lo_open=True),
    "f_c": Q("N", 0.0, 1e5, "kN", "5N"),
    "f_v": Q("N s/m", 0.0, 1e7, "N s/m", "25N s/m"),
}
"""``plant_sim.params.PlantParams`` field -> its magnitude."""

CONFIG = {
    "A1": Q("m^2", 1e-6, 1.0, "m^2", "80cm^2", lo_open=True),
    "A2": Q("m^2", 1e-6, 1.0, "m^2", "40cm^2", lo_open=True),
    "V10": Q("m^3", 1e-6, 10.0, "m^3", "110L", lo_open=True),
    "V20": Q("m^3", 1e-6, 10.0, "m^3", "90L", lo_open=True),
    "p_s": Q("Pa", 1e5, 1e8, "MPa", "12MPa"),
    "F_L": Q("N", -1e7, 1e7, "kN", "4kN"),
    "K_p": Q("", 0.0, 1e4, "", "1", lo_open=True),
    "K_f": Q("V/m", 1.0, 1e6, "V/m", "40V/m"),
    "sample_rate": Q("Hz", 1.0, 1e6, "Hz", "100Hz"),
    "x1_span": Q("m", 1e-3, 10.0, "m", "100mm"),
    "p_span": Q("Pa", 1e5, 1e9, "MPa", "12MPa"),
    "x5_span": Q("m", 1e-6, 0.1, "mm", "1mm"),
}
"""``hydromon.contract.RigConfig`` field -> its magnitude."""

CONTROLLER = {
    "K_i": Q("1/s", 0.0, 1e4, "1/s", "5/s"),
    "K_ff": Q("s", 0.0, 100.0, "s", "0.02s"),
}
"""``plant_sim.params.Controller`` field -> its magnitude (``--controller pi:ki=..,kff=..``)."""

MEMORY = Q("s", -math.inf, math.inf, "s", "10min")
"""The estimators' memory (``--memory``), a time; ``hydromon.cli.memory`` says how short it may be."""


def convert(values: dict, table: dict, what: str) -> dict:
    """``values`` (field -> number or text with a unit) with every field of ``table`` in SI;
    fields it does not know are left for the model to refuse."""
    return {k: parse(v, table[k], f"{what}{k}") if k in table else v for k, v in values.items()}


def unit_table(table: dict) -> list[tuple[str, str, str, str]]:
    """``(name, SI unit, sensible range, example)`` rows of a table, for docs and help."""
    return [(k, q.unit or "-", q.range_text(), q.example) for k, q in table.items()]
