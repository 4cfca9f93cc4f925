"""What a record must be for the audit to judge a model by it; a record that is not is refused.

The audit fits the model's equations on the first part of a record and compares how models
simulate the rest, so it needs every sensor alive, no sample off its course, readings in the
units the rig's config gives (SI), and a command that moves the rig in both parts. Each
``require_*`` raises ValueError saying what is wrong, where in the record, and what to give
instead; none changes the samples. Pure functions, SI units.
"""

from __future__ import annotations

import math

import numpy as np

from hydromon.contract import CHANNELS

from ..readings import unit_slip
from .signals import noise_levels
from .wiring import dead_words, exchanged_words

__all__ = ["require_auditable", "require_live_channels", "require_wired", "require_no_glitch",
           "require_in_range", "require_excitation",
           "find_glitch", "largest_excursion", "excitation_ratios", "held", "glitch_span", "GLITCH", "GLITCH_SPAN",
           "EXCITATION", "STILL"]

# Both steps of a glitch exceed GLITCH times the channel's 99th-percentile step. Over 2052 simulated
# records of the tuning sweeps (every profile, band, noise level, effect and rig size) no pair of
# opposite steps within GLITCH_SPAN came above 14 times it; a one-sample spike of 1 m in x1, 900
# MPa in x3 or 50 mm in x5 comes at 1600-25000 times it.
GLITCH = 50.0
GLITCH_SPAN = 2.0  # [s] the longest excursion read as a glitch (a dropout of the sensor's reading)
# In each part the command's rms as a position (ug / K_f) must exceed the position sensor's noise rms,
# and it or x1's rms EXCITATION times it (``held``); the tuning sweeps' commands reach 60 times it at
# least, a rig held at one command 0 (x1 creeping there 5-13 times it).
EXCITATION = 10.0
STILL = 1.0  # a command asking for no more motion than the position noise is held, however x1 moves
_TOP = 20  # largest steps of a channel paired in the glitch search
_PARTS = "(the first part fits, the rest scores; --train-fraction moves the split)"


def require_live_channels(samples: np.ndarray) -> None:
    """Refuse (ValueError naming them) samples ``ug, x1, x3, x4, x5`` in which a measured channel
    reads one value throughout (``monitor.audit.wiring.dead_channels``): it leaves singular
    equations, or none to fit, where a moving rig's sensors all vary."""
    why = dead_words(samples)
    if why:
        raise ValueError(f"{why} (the audit fits how the rig moves: every measured channel must vary)")


def require_wired(samples: np.ndarray, cfg) -> None:
    """Refuse (ValueError) samples whose chamber pressures x3 and x4 look exchanged
    (``monitor.audit.wiring``): every model would be judged on the wrong pressures."""
    why = exchanged_words(samples, cfg)
    if why:
        raise ValueError(f"{why}: the audit judges models by the chamber pressures, so mend the record first")


def largest_excursion(x: np.ndarray, span: int) -> tuple[int, int, float, float] | None:
    """The largest excursion of ``x`` that leaves its course in one step and comes back in one
    opposite step at most ``span`` samples later, among the channel's largest steps, measured by
    the smaller of its two steps over the channel's 99th-percentile step (its smallest nonzero
    step when 99 % of them are 0: a quantized sensor at rest); None when no two such steps are.

    Returns (first sample off course, first sample back, the step off course [unit of x], the
    smaller step over the scale [-]).
    """
    d = np.diff(np.asarray(x, dtype=float))
    a = np.abs(d)
    scale = float(np.quantile(a, 0.99)) if len(a) else 0.0
    if scale == 0.0:
        moving = a[a > 0]
        if not len(moving):
            return None
        scale = float(moving.min())
    top = np.argsort(-a)[:_TOP]
    best = None
    for i in top:
        for j in top:
            if 0 < j - i <= span and d[i] * d[j] < 0:
                ratio = min(a[i], a[j]) / scale
                if best is None or ratio > best[3]:
                    best = (int(i) + 1, int(j) + 1, float(d[i]), float(ratio))
    return best


def find_glitch(x: np.ndarray, span: int) -> tuple[int, int, float, float] | None:
    """``largest_excursion`` when both its steps exceed GLITCH times the scale, else None."""
    g = largest_excursion(x, span)
    return g if g is not None and g[3] > GLITCH else None


def excitation_ratios(samples: np.ndarray, K_f: float, split: int, noise: float | None = None
                      ) -> list[tuple[float, float]]:
    """For the samples before ``split`` and from it: the command's rms as a position (ug / K_f
    [V/m]) and x1's own rms, each over the position sensor's noise rms (x1's, from 4th
    differences) [-]; 0 where the channel stays at one value, inf where x1 shows no noise. x1's
    ratio does not depend on the unit x1 is written in; the command's does (through K_f): a record
    with x1 in mm asks a thousandth of the motion the rig makes. ``noise``: x1's noise rms [m]
    when the caller has it (default: ``noise_levels``)."""
    s = np.asarray(samples, dtype=float)
    if noise is None:
        noise = _x1_noise(s)
    out = []
    for rows in (slice(0, split), slice(split, len(s))):
        asked, moved = (0.0 if not len(x) or np.ptp(x) == 0.0 else float(np.std(x)) / k
                        for x, k in ((s[rows, 0], K_f), (s[rows, 1], 1.0)))
        out.append(tuple(r / noise if noise > 0 else math.inf if r > 0 else 0.0 for r in (asked, moved)))
    return out


def _x1_noise(s: np.ndarray) -> float:
    """x1's noise rms [m] (``noise_levels``), 0 for too few samples to tell."""
    return float(noise_levels(s)[0]) if len(s) > 4 else 0.0


def held(ratios: tuple[float, float]) -> bool:
    """A part held at one command (``excitation_ratios``): its command asks for no more motion than
    STILL times the position noise, or for no more than EXCITATION times it while x1 moves no more either. A
    piston settling or creeping under a held command moves, but the audit would compare only where
    models come to rest; a small command under a piston that moves far more is a unit or K_f
    error, which the audit's fit shows."""
    asked, moved = ratios
    return asked <= STILL or max(asked, moved) <= EXCITATION


def glitch_span(h: float) -> int:
    """GLITCH_SPAN in samples of period ``h`` [s]."""
    return max(1, int(round(GLITCH_SPAN / h)))


def _length(x: float) -> str:
    """A length [m] in mm from 1 mm up, else in um."""
    return f"{x * 1e3:.3g} mm" if abs(x) >= 1e-3 else f"{x * 1e6:.3g} um"


def _size(name: str, step: float) -> str:
    """A step of channel ``name`` in the unit a technician reads."""
    if name in ("x3", "x4"):
        return f"{step / 1e6:+.3g} MPa"
    if name == "ug":
        return f"{step:+.3g} V"
    return ("+" if step > 0 else "") + _length(step)


def require_no_glitch(samples: np.ndarray, h: float) -> None:
    """Refuse (ValueError naming the channel, the samples and the times) samples ``ug, x1, x3, x4,
    x5`` at period ``h`` [s] in which a measured channel leaves its course and comes back
    (``find_glitch``): a spike or a dropout of the sensor's reading is fitted as if the rig had
    moved that way: a one-sample spike of x1 reads as a 35 kN load offset."""
    s = np.asarray(samples, dtype=float)
    span = glitch_span(h)
    for k, name in enumerate(CHANNELS[1:], 1):
        g = find_glitch(s[:, k], span)
        if g is None:
            continue
        off, back, step, ratio = g
        where = (f"at sample {off} (t = {off * h:.2f} s)" if back == off + 1 else
                 f"from sample {off} to {back - 1} (t = {off * h:.2f}-{(back - 1) * h:.2f} s)")
        raise ValueError(f"{name} jumps {_size(name, step)} {where} and back, in steps {ratio:.0f} times larger than "
                         f"99 % of its steps: a spike or dropout of the sensor, which the audit would fit as motion "
                         f"of the rig; cut the record before or after it, or mend those samples")


def require_in_range(samples: np.ndarray, cfg) -> None:
    """Refuse (ValueError naming the channel, its reading and the config's constant) samples ``ug,
    x1, x3, x4, x5`` whose readings the rig's config ``cfg`` cannot hold (``monitor.readings``): a
    channel in other units than SI, or a config that is not the rig's. Models fitted to them fit
    the units: pressures in bar read as a rig that does not obey the model, a spool in 0.01 mm
    as a clean record."""
    why = unit_slip(samples, cfg)
    if why is not None:
        raise ValueError(why)


def require_excitation(samples: np.ndarray, K_f: float, split: int, h: float) -> None:
    """Refuse (ValueError naming the part and its times) samples ``ug, x1, x3, x4, x5`` at period
    ``h`` [s] held at one command (``held``) in the part that fits (before sample ``split``) or
    in the part that scores (from it). A rig held at one command tells models apart only by where
    each comes to rest, which a free run's held-out error then reads as dynamics (a rig held still
    reads as a 12-sample sensor delay). The words tell a command that stays at one value from one
    far smaller than the motion (ug in other units) and from one lost in an x1 too noisy to audit."""
    s = np.asarray(samples, dtype=float)
    noise = _x1_noise(s)
    for part, rows, ratios in zip(("fitting", "held-out"), (slice(0, split), slice(split, len(s))),
                                  excitation_ratios(s, K_f, split, noise)):
        if held(ratios):
            ug, x1 = s[rows, 0], s[rows, 1]
            first, last = rows.indices(len(s))[:2]
            where = f"in the {part} part (t = {first * h:.2f}-{(last - 1) * h:.2f} s)"
            against = f"against a position sensor's noise of {_length(noise)} rms"
            if np.ptp(ug) == 0.0:
                raise ValueError(
                    f"the rig is held at one command {where}: the command ug stays at {ug[0]:.6g} V and x1 moves "
                    f"{_length(np.std(x1))} rms, {against}; models cannot be told apart by where they come to rest. "
                    f"Audit a record whose command varies in both parts {_PARTS}")
            asked = f"{np.std(ug):.3g} V rms ({_length(np.std(ug) / K_f)} as a position, ug / K_f)"
            if ratios[1] > EXCITATION:
                raise ValueError(
                    f"the command asks for almost no motion {where} while the rig moves: ug varies {asked} and x1 "
                    f"{_length(np.std(x1))} rms, {against}: a rig settling under a held command, or ug logged in "
                    f"other units than V (or a K_f that is not the rig's). Audit a record whose command moves the rig "
                    f"in both parts {_PARTS}")
            raise ValueError(
                f"too little motion above the position noise {where}: the command ug varies {asked} and x1 "
                f"{_length(np.std(x1))} rms, {against}: "
                f"a rig held still, or an x1 too noisy (or too coarse) to audit; models cannot be told apart there. "
                f"Audit a record whose command moves the rig in both parts {_PARTS}")


def require_auditable(samples: np.ndarray, cfg, split: int) -> None:
    """Every check of this module, in the order a person would mend the record: a dead sensor,
    a glitch, readings the rig's config ``cfg`` cannot hold, too little excitation (``split``
    as ``require_excitation``), then exchanged chamber pressures."""
    require_live_channels(samples)
    s = np.asarray(samples, dtype=float)
    h = cfg.h
    if s.ndim != 2 or s.shape[1] != 5 or len(s) < 5 or not np.all(np.isfinite(s)) or not (h > 0 and math.isfinite(h)):
        return  # ``signals`` says what is wrong with these (a config at an infinite sample rate has h = 0)
    require_no_glitch(s, h)
    require_in_range(s, cfg)
    require_excitation(s, cfg.K_f, split, h)
    require_wired(s, cfg)
