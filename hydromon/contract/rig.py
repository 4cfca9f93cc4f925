"""The rig constants: what a monitor knows of a rig, published on ``<ns>/rig/<id>/config``.

SI throughout: m^2, m^3, Pa, N, V/V, V/m, Hz, m. The defaults are the reference rig of the
method (A1 = 0.008 m^2, area ratio 2; p_s = 12 MPa; F_L = 4000 N; K_p = 1; K_f = 40 V/m);
a real rig supplies its own.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

__all__ = ["RigConfig"]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class RigConfig(_Model):
    """Constants of one rig that the monitor knows (published on ``<ns>/rig/<id>/config``).

    Attributes
    ----------
    A1, A2 : float
        Effective piston areas, cap and rod side [m^2]. The paper omits A1; 0.008 m^2.
    V10, V20 : float
        Chamber volumes at x1 = 0, including the pipe volumes [m^3] (eqs 12-13).
    p_s : float
        Supply pressure [Pa].
    F_L : float
        Configured external load force [N].
    K_p : float
        Proportional controller gain [V/V] (eq 2).
    K_f : float
        Position sensor gain [V/m] (eq 2).
    sample_rate : float
        Sample rate of the published channels [Hz].
    x1_span, p_span, x5_span : float
        Full-scale span of the position [m], pressure [Pa] and spool [m] sensors; the
        "stress" noise model is 0.1 % of these, and a reading beyond 10 times its sensor's
        span is taken for one in other units (the rig's health says bad-input).
    """

    A1: float = Field(0.008, gt=0)
    A2: float = Field(0.004, gt=0)
    V10: float = Field(0.11, gt=0)
    V20: float = Field(0.09, gt=0)
    p_s: float = Field(12e6, gt=0)
    F_L: float = 4000.0
    K_p: float = Field(1.0, gt=0)
    K_f: float = Field(40.0, gt=0)
    sample_rate: float = Field(100.0, gt=0)
    x1_span: float = Field(0.1, gt=0)
    p_span: float = Field(12e6, gt=0)
    x5_span: float = Field(1e-3, gt=0)

    @property
    def h(self) -> float:
        """Sample period [s]."""
        return 1.0 / self.sample_rate
