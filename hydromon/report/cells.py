"""What the live health tables show (``hydromon demo``, ``hydromon watch``): the parameters in
their columns, how a number is written, and the colour of each grade."""

from __future__ import annotations

__all__ = ["GRADE_STYLE", "TABLE_PARAMS", "fmt_value"]

TABLE_PARAMS = ("K_sv", "f_c", "B_fv", "C_ip")
"""Parameters shown in the live tables (SI: m/V, N, N s/m, m^3/(s Pa)): the graded ones."""

GRADE_STYLE = {"health": "green", "sub-health": "green3", "average": "yellow", "deterioration": "dark_orange",
               "fault": "red", "unknown": "dim"}
"""rich style of each grade's name."""


def fmt_value(v) -> str:
    """A parameter value in a table cell: ``-`` when absent, whole numbers from 1e3 to 1e6 (a
    damping of 6025 N s/m), else three significant digits."""
    if v is None:
        return "-"
    return f"{v:.0f}" if 1e3 <= abs(v) < 1e6 else f"{v:.3g}"
