"""Wiring mistakes a whole record shows: a sensor that reads one value throughout, a valve drive
``u`` logged at one value while the spool moves, and the two chamber pressures logged the other
way round.

None of them makes an estimate physically impossible (``monitor.plausibility``), so without
these checks such a record is graded as if it were right: a healthy rig's 30 s record with x3
and x4 exchanged was graded ``health``, ``ok``, and commissioned, and so was one whose x3 read
5 MPa in every sample; a drive of zeros left the valve gain at 0, ungraded, and the grade
``health``. ``evaluate``, ``commission`` and the audit ask them before they trust a record (the
recording reader refuses a dead drive). Pure functions, SI units.

Exchanged pressures. The nominal model's equations (``monitor.audit.equations``) are fitted to
the record as it is and with x3 and x4 exchanged. On a rig wired right, the exchange breaks the
valve's flow law in both chamber equations and turns the force balance's piston force into
another combination of the pressures (the areas differ), so both fit worse. The record is called
exchanged when the exchange makes *both* the chamber equations' and the force balance's residual
variance smaller by more than a factor of e^``EXCHANGE_LOG`` and the exchanged fit is possible:
its mass, compressibility and orifice coefficient positive. A dead band a tenth of the spool's
span, at stress noise, broke the nominal fit so far (1/beta_e negative) that the exchange fitted
both better, with a negative mass: possible fits are what a wiring mistake leaves.

``python benchmarks/wiring_scan.py --seed-base B --effects`` counts the calls on the audit's
records (20 s, every input shape and health band, reference and random rigs, no, realistic and
stress noise): each record as it is (a call is a false alarm) and exchanged (a call is a
detection), clean and with each effect at its largest magnitude. docs/limits.md gives the
figures. A large effect breaks the chamber equations whichever way round the pressures are, so
there an exchanged record is often not called: the check names a mistake, it does not prove the
wiring right.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hydromon.contract import CHANNELS, RigConfig

from ..readings import longest_stretch
from .equations import _Equations

__all__ = ["DRIVE_SAMPLES_S", "EXCHANGE_LOG", "SPOOL_MOVES", "Exchange", "dead_channels", "dead_drive_words",
           "dead_words", "exchange", "exchanged_words", "wiring_words"]

EXCHANGE_LOG = 0.5
"""Log factor [-] by which exchanging x3 and x4 must lower both the chamber equations' and the
force balance's residual variance for a record to be called exchanged (module docstring)."""

SPOOL_MOVES = 0.01
"""Share [-] of the spool's span (``x5_span``) that x5 must travel for a constant drive to be
dead, or a held pressure stuck (``hydromon.engine.stuck_watch``): 10 um on the default 1 mm
span, where a held spool's sensor noise spans a few um (6.5 um over 10 s at stress noise)."""

DRIVE_SAMPLES_S = 2.0
"""Samples [s, at the config's rate] that must carry a drive for a constant one to be dead: a
few samples that happen to carry one say nothing of the valve."""

_EXCHANGED = [0, 1, 3, 2, 4]  # ug, x1, x4, x3, x5
_POSITIVE = ("m", "inv_beta_e", "CdW_sqrt_rho")  # what the exchanged fit must have positive to be called
_TRAIN = 0.7  # the equations' floors want a held-out part; the residuals compared are over every row


def dead_channels(samples: np.ndarray) -> tuple[tuple[str, float], ...]:
    """The measured channels (x1, x3, x4, x5) of ``samples`` (N, 5: ug, x1, x3, x4, x5, SI) that
    read one value in every sample, with that value; none for a record that is not (N, 5) and
    finite (its reader says what is wrong with it)."""
    s = np.asarray(samples, dtype=float)
    if s.ndim != 2 or s.shape[1] != 5 or not len(s) or not np.all(np.isfinite(s)):
        return ()
    return tuple((name, float(s[0, k])) for k, name in enumerate(CHANNELS[1:], 1) if np.ptp(s[:, k]) == 0.0)


def dead_words(samples: np.ndarray) -> str | None:
    """Why a record whose measured channel reads one value throughout cannot be trusted (None:
    every measured channel varies)."""
    flat = dead_channels(samples)
    if not flat:
        return None
    still = " (or a piston that never moved)" if flat[0][0] == "x1" else ""
    return (", ".join(f"{name} is {value:.6g}" for name, value in flat) + " in every sample: a sensor that is not "
            f"logged, stuck, or written with too few decimals{still}")


def dead_drive_words(u: np.ndarray, x5: np.ndarray, config: RigConfig) -> str | None:
    """Why a record's valve drive ``u`` [V] cannot be trusted when it reads one value in every
    sample that carries it while the spool ``x5`` [m] of those samples moves by more than
    ``SPOOL_MOVES`` of its span (the spool follows its drive); None: it varies, the spool holds
    still too (a held drive), or fewer than ``DRIVE_SAMPLES_S`` seconds of samples carry it."""
    u, x5 = np.asarray(u, dtype=float), np.asarray(x5, dtype=float)
    if len(u) < DRIVE_SAMPLES_S * config.sample_rate or np.ptp(u) != 0.0:
        return None
    if not np.ptp(x5) > SPOOL_MOVES * config.x5_span:
        return None
    return (f"u (the valve drive) is {u[0]:.6g} V in every sample that carries it while the spool moves "
            f"{1e3 * np.ptp(x5):.3g} mm: a drive not logged, or stuck (without the column the rig constants' loop "
            "gives the valve's input)")


def _mse(eq: _Equations, block: str) -> float:
    """The nominal fit's residual variance of one block over all its rows [block unit^2]."""
    fit = eq.nominal
    return fit.mse(block, np.ones(len(fit.blocks[block].rows), dtype=bool))


@dataclass(frozen=True)
class Exchange:
    """What exchanging x3 and x4 does to a record's nominal fit."""

    chamber: float  # log factor [-] by which the exchange lowers the chamber equations' residual variance
    force: float  # the same for the force balance (negative: the exchange fits worse)
    possible: bool  # the exchanged fit's m, 1/beta_e and orifice coefficient are all positive

    @property
    def called(self) -> bool:
        """The record looks exchanged (module docstring)."""
        return self.possible and min(self.chamber, self.force) > EXCHANGE_LOG


def exchange(samples: np.ndarray, config: RigConfig) -> Exchange | None:
    """What exchanging x3 and x4 does to the record's nominal fit, or None when its equations
    cannot be fitted either way round (too short, or the rig at rest). ``samples`` (N, 5): ug
    [V], x1 [m], x3 [Pa], x4 [Pa], x5 [m], one stretch without a gap."""
    s = np.asarray(samples, dtype=float)
    try:
        as_is = _Equations(s, config, _TRAIN)
        other = _Equations(s[:, _EXCHANGED], config, _TRAIN)
        c, f = (math.log(_mse(as_is, g) / _mse(other, g)) for g in ("chamber", "force"))
    except (ValueError, np.linalg.LinAlgError, ZeroDivisionError):
        return None
    if not (math.isfinite(c) and math.isfinite(f)):
        return None
    return Exchange(c, f, all(other.p_nom[k] > 0 for k in _POSITIVE))


def exchanged_words(samples: np.ndarray, config: RigConfig) -> str | None:
    """Why the record's x3 and x4 look exchanged (module docstring), or None: they do not, or
    the record cannot tell (``samples`` as in :func:`exchange`)."""
    e = exchange(samples, config)
    if e is None or not e.called:
        return None
    return (f"x3 and x4 look exchanged: read the other way round, they fit the chamber equations "
            f"{math.exp(e.chamber):.3g} times better and the force balance {math.exp(e.force):.3g} times better "
            "(x3 is the cap side's pressure, on area A1; x4 the rod side's, on A2)")


def wiring_words(samples: np.ndarray, config: RigConfig, restarts=()) -> str | None:
    """The first wiring mistake a record shows, in words: a dead channel, else exchanged
    pressures (judged on its longest stretch without a gap: the equations differentiate from
    sample to sample); None: neither. ``samples`` (N, 5): ug [V], x1 [m], x3 [Pa], x4 [Pa],
    x5 [m]; ``restarts``: the samples that follow gaps."""
    lo, hi = longest_stretch(len(samples), restarts)
    return dead_words(samples) or exchanged_words(np.asarray(samples)[lo:hi], config)
