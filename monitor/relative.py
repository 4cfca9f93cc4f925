"""Health relative to a rig's own baseline: how far it has degraded from itself when new.

The reference ranges (``Ranges.default()``, made for the reference rig) place each graded
parameter's band edges in absolute units. A rig of another size, supply, valve or load has other
healthy values, so the same edges would grade it by its size, not its health. The bands are
therefore read as ratios to the reference rig's healthy values (Table 1 of the method's paper:
the ``PlantParams()`` defaults), and carried over to a rig by its own healthy values, its
*baseline*:

    edge(rig) = edge(reference) * baseline(rig) / healthy(reference)

for K_sv, f_c, B + f_v and C_d W / sqrt(rho) (where graded); a valve that has lost 12 % of its gain
is at the sub-health edge whatever its size. A leakage has no healthy value to be relative to (a
new rig's external leakage is zero), so its fault threshold scales with what makes a leakage
harmful: the leakage flow against the valve's flow, ``plant_sim.degradation.leak_scale`` of the
rig's baseline orifice coefficient and valve gain and its supply pressure.

On the reference rig (baseline = its healthy values, the reference constants) every factor is
exactly 1, so the reference ranges come back unchanged, bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from hydromon.contract import RigConfig
from plant_sim.degradation import leak_scale
from plant_sim.params import PlantParams

from .ranges import ParamRange, Ranges

__all__ = ["REFERENCE_HEALTHY", "relative_factor", "relative_ranges"]

REFERENCE_HEALTHY = PlantParams().identified()
"""The reference rig's healthy parameter values [SI], by bus name."""


def relative_factor(name: str, baseline: Mapping[str, float], config: RigConfig) -> float:
    """The factor [-] that carries parameter ``name``'s reference edges over to a rig with this
    ``baseline`` [SI, by bus name] and constants ``config``; NaN when the baseline cannot carry
    them (a non-positive or missing healthy value)."""
    if name in ("C_ip", "C_ep"):
        cdw, ksv = baseline.get("CdW_sqrt_rho", math.nan), baseline.get("K_sv", math.nan)
        if not (cdw > 0 and ksv > 0):
            return math.nan
        ref = leak_scale(REFERENCE_HEALTHY["CdW_sqrt_rho"], REFERENCE_HEALTHY["K_sv"], RigConfig().p_s)
        return leak_scale(cdw, ksv, config.p_s) / ref
    value = baseline.get(name, math.nan)
    if not value > 0:
        return math.nan
    return value / REFERENCE_HEALTHY[name]


def relative_ranges(baseline: Mapping[str, float], config: RigConfig, reference: Ranges | None = None,
                    names=None) -> tuple[Ranges, dict[str, str]]:
    """The reference ranges carried over to a rig with this ``baseline`` and ``config``:
    ``(ranges made for config, {name: why left out})``. ``names`` limits the graded
    parameters (default: every one the reference grades); a parameter whose baseline cannot
    carry its bands (:func:`relative_factor` NaN) is left out with the reason."""
    reference = reference or Ranges.default()
    params, left_out = {}, {}
    for name, pr in reference.params.items():
        if names is not None and name not in names:
            continue
        f = relative_factor(name, baseline, config)
        if not math.isfinite(f):
            left_out[name] = f"its healthy value {baseline.get(name, math.nan):.4g} cannot carry relative bands"
            continue
        if pr.edges is not None:
            params[name] = ParamRange(direction=pr.direction, edges=tuple(e * f for e in pr.edges))
        else:
            params[name] = ParamRange(direction=pr.direction, fault_threshold=pr.fault_threshold * f)
    if not params:
        raise ValueError("no graded parameter left: " + "; ".join(f"{k}: {v}" for k, v in left_out.items()))
    return Ranges(params=params, rig=config, source="the reference ranges relative to the rig's baseline"), left_out
