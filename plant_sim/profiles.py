"""Command-voltage input profiles ug(t) [V], vectorised over time t [s].

Each profile is a small frozen object with ``__call__(t) -> ug``; ``parse_profile``
turns the CLI's ``name[:key=value,...]`` strings into one.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hydromon.contract import SAMPLE_LIMITS

__all__ = [
    "Profile", "PaperIdentification", "PaperVariable", "Steps", "Chirp", "Multisine",
    "FromFile", "parse_profile", "PROFILE_NAMES",
]


class Profile:
    """Base class: ``profile(t)`` returns ug [V] at the times t [s]."""

    name = "profile"

    def __call__(self, t: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def spec(self) -> str:
        """The string ``parse_profile`` turns back into this profile."""
        fields = {k: v for k, v in self.__dict__.items()}
        args = ",".join(f"{k}={v}" for k, v in fields.items())
        return f"{self.name}:{args}" if args else self.name


@dataclass(frozen=True)
class PaperIdentification(Profile):
    """Paper section 3.3: ug = offset + amplitude sin(2 pi f t), defaults 2 + sin(2 pi t)."""

    offset: float = 2.0
    amplitude: float = 1.0
    freq: float = 1.0
    name = "paper-id"

    def __call__(self, t):
        return self.offset + self.amplitude * np.sin(2 * math.pi * self.freq * np.asarray(t, float))


@dataclass(frozen=True)
class PaperVariable(Profile):
    """Paper section 4.2 (garbled in print, read as): 0.5 sin(5 pi t) plus a level of
    2.5 V for t <= T/4 or T/2 < t <= 3T/4, else 2 V. ``period`` is T [s]; the pattern repeats."""

    period: float = 10.0
    name = "paper-var"

    def __call__(self, t):
        t = np.asarray(t, float)
        phase = np.mod(t, self.period) / self.period
        high = ((phase <= 0.25) | ((phase > 0.5) & (phase <= 0.75))) & ~((phase == 0) & (t > 0))
        return 0.5 * np.sin(5 * math.pi * t) + np.where(high, 2.5, 2.0)


@dataclass(frozen=True)
class Steps(Profile):
    """Square wave between ``low`` and ``high`` [V] with period [s] (a staircase of steps)."""

    low: float = 1.5
    high: float = 2.5
    period: float = 2.0
    name = "steps"

    def __call__(self, t):
        t = np.asarray(t, float)
        return np.where(np.mod(t, self.period) < self.period / 2, self.high, self.low)


@dataclass(frozen=True)
class Chirp(Profile):
    """offset + amplitude sin(phase), frequency rising linearly f0 -> f1 [Hz] over sweep [s], repeating."""

    offset: float = 2.0
    amplitude: float = 0.5
    f0: float = 0.1
    f1: float = 5.0
    sweep: float = 10.0
    name = "chirp"

    def __call__(self, t):
        tau = np.mod(np.asarray(t, float), self.sweep)
        phase = 2 * math.pi * (self.f0 * tau + 0.5 * (self.f1 - self.f0) / self.sweep * tau**2)
        return self.offset + self.amplitude * np.sin(phase)


@dataclass(frozen=True)
class Multisine(Profile):
    """offset + sum of equal sines at freqs [Hz] with Schroeder phases (low crest factor)."""

    offset: float = 2.0
    amplitude: float = 0.8
    freqs: tuple = (0.3, 0.7, 1.3, 2.9, 4.1)
    name = "multisine"

    def __call__(self, t):
        t = np.asarray(t, float)
        n = len(self.freqs)
        out = np.full_like(t, self.offset)
        for k, f in enumerate(self.freqs, start=1):
            phi = -math.pi * k * (k - 1) / n
            out += self.amplitude / math.sqrt(n) * np.sin(2 * math.pi * f * t + phi)
        return out

    def spec(self):
        return f"multisine:offset={self.offset},amplitude={self.amplitude},freqs={'/'.join(map(str, self.freqs))}"


@dataclass(frozen=True)
class FromFile(Profile):
    """ug read from a CSV with columns ``t,ug`` (SI), linearly interpolated, held beyond its ends."""

    path: str = ""
    t_data: np.ndarray = field(default=None, repr=False, compare=False)
    u_data: np.ndarray = field(default=None, repr=False, compare=False)
    name = "file"

    # [V] a command beyond this is not a servo-valve voltage (the bus contract's ug limit; a
    # file in mV or raw counts): refused rather than simulated into out-of-contract samples
    UG_LIMIT = SAMPLE_LIMITS["ug"]

    @classmethod
    def load(cls, path: str | Path) -> "FromFile":
        try:
            with open(path, newline="") as fh:
                reader = csv.DictReader(fh)
                rows = [(reader.line_num, r) for r in reader]
        except FileNotFoundError:
            raise FileNotFoundError(f"profile file {str(path)!r}: no such file") from None
        except (IsADirectoryError, PermissionError, UnicodeDecodeError) as exc:
            raise ValueError(f"profile file {str(path)!r}: cannot be read as CSV text ({exc.__class__.__name__})") from None
        if not rows or "t" not in rows[0][1] or "ug" not in rows[0][1]:
            raise ValueError(f"{path}: a profile file needs a header with columns t,ug")
        t, u = np.empty(len(rows)), np.empty(len(rows))
        for i, (line, r) in enumerate(rows):
            try:
                t[i], u[i] = float(r["t"]), float(r["ug"])
            except (TypeError, ValueError):  # a short row gives None (TypeError), text ValueError
                raise ValueError(f"{path}: line {line}: t and ug must be numbers, got "
                                 f"t={r['t']!r}, ug={r['ug']!r}") from None
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(u))):
            raise ValueError(f"{path}: non-finite t or ug")
        big = np.flatnonzero(np.abs(u) > cls.UG_LIMIT)
        if big.size:
            line, _ = rows[int(big[0])]
            raise ValueError(f"{path}: line {line}: ug = {float(u[big[0]])!r} V is beyond +-{cls.UG_LIMIT:g} V "
                             "(ug in volts, SI; mV or raw counts?)")
        if np.any(np.diff(t) <= 0):
            raise ValueError(f"{path}: t must increase strictly")
        return cls(path=str(path), t_data=t, u_data=u)

    def __call__(self, t):
        return np.interp(np.asarray(t, float), self.t_data, self.u_data)

    def spec(self):
        return f"file:path={self.path}"


_KINDS = {c.name: c for c in (PaperIdentification, PaperVariable, Steps, Chirp, Multisine)}
PROFILE_NAMES = tuple(_KINDS) + ("file",)


def parse_profile(spec: str) -> Profile:
    """Parse ``name[:key=value,...]``, e.g. ``paper-var:period=10`` or ``file:path=u.csv``."""
    name, _, rest = spec.partition(":")
    kwargs = {}
    for item in filter(None, rest.split(",")):
        key, eq, value = item.partition("=")
        if not eq:
            raise ValueError(f"profile {spec!r}: expected key=value, got {item!r}")
        kwargs[key.strip()] = value.strip()
    if name == "file":
        if "path" not in kwargs:
            raise ValueError("profile 'file' needs path=FILE")
        return FromFile.load(kwargs["path"])
    if name not in _KINDS:
        raise ValueError(f"unknown profile {name!r}; choose from {', '.join(PROFILE_NAMES)}")
    cls = _KINDS[name]
    try:
        if name == "multisine" and "freqs" in kwargs:
            kwargs["freqs"] = tuple(float(f) for f in kwargs["freqs"].split("/"))
        typed = {k: (v if k == "freqs" else float(v)) for k, v in kwargs.items()}
        prof = cls(**typed)
    except TypeError as exc:
        raise ValueError(f"profile {spec!r}: {exc}") from None
    _check_values(spec, prof)
    return prof


#: fields a profile divides by or takes the period of: must be > 0
_POSITIVE = ("period", "sweep", "freq")


def _check_values(spec: str, prof: Profile) -> None:
    """Every value finite, periods/sweeps/frequencies > 0, and the command's worst case within
    the contract's |ug| limit: otherwise a simulation writes NaN or out-of-contract samples
    (or divides by zero) instead of one error line."""
    values = {k: v for k, v in prof.__dict__.items() if isinstance(v, float)}
    freqs = getattr(prof, "freqs", None)
    if isinstance(freqs, tuple):
        values.update({f"freqs[{i}]": f for i, f in enumerate(freqs)})
    for k, v in values.items():
        if not math.isfinite(v):
            raise ValueError(f"profile {spec!r}: {k} = {v!r} must be a finite number")
        if (k in _POSITIVE or k.startswith("freqs[")) and v <= 0:
            raise ValueError(f"profile {spec!r}: {k} = {v!r} must be > 0")
    if isinstance(prof, Chirp) and (prof.f0 < 0 or prof.f1 < 0):
        raise ValueError(f"profile {spec!r}: f0 and f1 must be >= 0 Hz")
    if isinstance(prof, Steps):
        bound = max(abs(prof.low), abs(prof.high))
    elif isinstance(prof, PaperVariable):
        bound = 3.0  # its 2.5 V level + 0.5 V sine (only its period is a parameter)
    else:
        bound = abs(getattr(prof, "offset", 0.0)) + abs(getattr(prof, "amplitude", 0.0))
    if bound > FromFile.UG_LIMIT:  # the bus contract's |ug| limit, as for a profile file
        raise ValueError(f"profile {spec!r}: the command would reach {bound:g} V, beyond +-{FromFile.UG_LIMIT:g} V "
                         "(ug in volts, SI)")
