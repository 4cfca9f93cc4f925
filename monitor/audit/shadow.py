"""A load offset that is a Stribeck hump's shadow.

What a hump leaves in the force equation's residual once Coulomb and viscous friction have
taken their share need not be orthogonal to a constant over a record's sliding rows, and a
constant force (a load offset) may then score on the equations as well as the hump itself (an
80 N hump at realistic noise on paper-var scored 0.51 as a 53 N offset and 0.50 as a hump).
Fitted together, the two separate: a constant force keeps its value beside a hump, odd in v,
while an offset the equations fitted to a hump falls to a fraction of itself.
``offset_shadow`` makes that test for a load offset that earned its place.
"""

from __future__ import annotations

from .candidates import StribeckFriction

__all__ = ["SHADOW", "offset_shadow"]

SHADOW = 0.5
"""Share of a load offset [-] that must remain when Stribeck friction is fitted beside it for
the offset to stay a cause. Tuning base 11700000: on the load-offset ladder (160 records, 100 to
3200 N, every profile and band, noise none and realistic) the joint fit kept 0.98-1.03 of the
offset; on the Stribeck ladder's records named a load offset, an 80 N hump at realistic noise on
paper-id and paper-var kept 0.17-0.24 of it (9-12 N of 49-53 N), and 160 N on steps 0.78."""


def offset_shadow(earn, results, pair) -> dict:
    """The load offset among ``earn`` (candidate results that earned their place) that a
    Stribeck hump fitted beside it takes the place of: {"load_offset": words}, or {}.

    ``pair(first, second)`` fits two candidates together and returns (score, fit, effects) or
    None (``monitor.audit.decide.decide``). The hump must be one (F_s > 0 at a Stribeck
    velocity a breakaway hump has) for the offset to be its shadow."""
    lo = next((c for c in earn if c.name == "load_offset"), None)
    if lo is None or not any(c.name == "stribeck_friction" for c in results):
        return {}
    alone = lo.effect.get("load_offset", 0.0)
    got = pair("load_offset", "stribeck_friction")
    if got is None or alone == 0.0 or not StribeckFriction().plausible(got[2]):
        return {}
    eff = got[2]
    kept = eff["load_offset"] / alone
    if kept >= SHADOW:
        return {}
    return {"load_offset": (
        f"load_offset scores {lo.score:.2f}, but fitted beside a Stribeck hump ({eff['stribeck_F_s']:.0f} N "
        f"fading over {1e3 * eff['stribeck_v_s']:.0f} mm/s) the offset falls from {alone:.0f} N to "
        f"{eff['load_offset']:.0f} N: what it fitted is the hump's, not a constant force")}
