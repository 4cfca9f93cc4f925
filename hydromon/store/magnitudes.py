"""Physical magnitudes with units, as people write them in options and files: ``5um``, ``40N``,
``0.3mm``, ``12MPa``, ``2.5e-4m/V``, ``60 bar``; a bare number is SI.

One parser for every magnitude hydromon takes (effects, plant parameters, rig constants, the
controller's gains, the estimators' memory): :func:`parse` reads a number and an optional unit,
converts it to the SI unit of the :class:`Quantity` asked for, and refuses a unit of another
dimension or a magnitude outside the quantity's physically sensible range, in one line that
names the range and the unit it assumed ("valve_dead_band 2.5 m is outside 0..1 mm: give a
unit, e.g. 2.5um").

Units are products and quotients of symbols with SI prefixes (G M k c m u µ n p) and integer
powers: ``m/V``, ``N s/m``, ``m^3/(s Pa)``, ``bar/(L/min)``, ``cm^2``. Symbols: m, g, s, min,
h, A, V, N, Pa, bar, psi, L (or l), Hz, rad, %, samples. Hz counts cycles: ``16Hz`` for an
angular frequency in rad/s is 100.5 rad/s, never 16.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from decimal import Decimal

__all__ = ["Quantity", "parse", "parse_unit", "MagnitudeError"]

# dimensions: exponents of m, kg, s, A, rad, sample
_DIMS = ("m", "kg", "s", "A", "rad", "sample")


def _d(**exp: int) -> tuple[int, ...]:
    return tuple(exp.get(k, 0) for k in _DIMS)


_SYMBOLS: dict[str, tuple[float, tuple[int, ...], bool]] = {
    # symbol: (factor to SI, dimension, takes a prefix)
    "m": (1.0, _d(m=1), True),
    "g": (1e-3, _d(kg=1), True),
    "s": (1.0, _d(s=1), True),
    "min": (60.0, _d(s=1), False),
    "h": (3600.0, _d(s=1), False),
    "A": (1.0, _d(A=1), True),
    "V": (1.0, _d(kg=1, m=2, s=-3, A=-1), True),
    "N": (1.0, _d(kg=1, m=1, s=-2), True),
    "Pa": (1.0, _d(kg=1, m=-1, s=-2), True),
    "bar": (1e5, _d(kg=1, m=-1, s=-2), True),
    "psi": (6894.757293168, _d(kg=1, m=-1, s=-2), False),
    "L": (1e-3, _d(m=3), True),
    "l": (1e-3, _d(m=3), True),
    "Hz": (2.0 * math.pi, _d(rad=1, s=-1), True),  # a cycle is 2 pi rad
    "rad": (1.0, _d(rad=1), False),
    "%": (0.01, _d(), False),
    "-": (1.0, _d(), False),
    "sample": (1.0, _d(sample=1), False),
    "samples": (1.0, _d(sample=1), False),
    "1": (1.0, _d(), False),  # 1/s
}
_PREFIXES = {"G": 1e9, "M": 1e6, "k": 1e3, "c": 1e-2, "m": 1e-3, "u": 1e-6, "µ": 1e-6, "μ": 1e-6, "n": 1e-9,
             "p": 1e-12}
_NUMBER = re.compile(r"\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|[+-]?inf)\s*(.*?)\s*$", re.IGNORECASE)
_TOKEN = re.compile(r"\s*(\(|\)|/|\*|·|\^[+-]?\d+|[A-Za-zµμ%-]+|1(?![\d.]))")


class MagnitudeError(ValueError):
    """A magnitude that cannot be read, of the wrong dimension, or outside its sensible range."""


def _symbol(sym: str) -> tuple[float, tuple[int, ...]]:
    if sym in _SYMBOLS:
        f, d, _ = _SYMBOLS[sym]
        return f, d
    if len(sym) > 1 and sym[0] in _PREFIXES and sym[1:] in _SYMBOLS and _SYMBOLS[sym[1:]][2]:
        f, d, _ = _SYMBOLS[sym[1:]]
        return _PREFIXES[sym[0]] * f, d
    raise MagnitudeError(f"unknown unit {sym!r}")


def parse_unit(text: str) -> tuple[float, tuple[int, ...]]:
    """``(factor to SI, dimension)`` of a unit such as ``um``, ``m^3/(s Pa)`` or ``bar/(L/min)``."""
    text = text.strip()
    if text.startswith("/"):  # "5/s": the number is the numerator
        text = "1" + text
    tokens, pos = [], 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            raise MagnitudeError(f"cannot read the unit {text!r}")
        tokens.append(m.group(1))
        pos = m.end()
    tokens = [t for t in tokens if t not in ("*", "·")]  # a product is also written with a space
    at = 0

    def factor():
        nonlocal at
        if at >= len(tokens):
            raise MagnitudeError(f"cannot read the unit {text!r}")
        tok = tokens[at]
        at += 1
        if tok == "(":
            f, d = product()
            if at >= len(tokens) or tokens[at] != ")":
                raise MagnitudeError(f"unbalanced parentheses in the unit {text!r}")
            at += 1
        elif tok in (")", "/") or tok.startswith("^"):
            raise MagnitudeError(f"cannot read the unit {text!r}")
        else:
            f, d = _symbol(tok)
        if at < len(tokens) and tokens[at].startswith("^"):
            p = int(tokens[at][1:])
            at += 1
            f, d = f ** p, tuple(x * p for x in d)
        return f, d

    def product():
        nonlocal at
        f, d = factor()
        while at < len(tokens) and tokens[at] != ")":
            divide = tokens[at] == "/"
            at += divide
            g, e = factor()
            f, d = (f / g, tuple(a - b for a, b in zip(d, e))) if divide else (f * g, tuple(a + b for a, b in zip(d, e)))
        return f, d

    f, d = product()
    if at != len(tokens):
        raise MagnitudeError(f"cannot read the unit {text!r}")
    return f, d


@dataclass(frozen=True)
class Quantity:
    """What a magnitude is: its SI ``unit`` (what a bare number means), its sensible range
    ``lo``..``hi`` in SI (``lo_open``: lo itself excluded), the ``shown`` unit the range is
    stated in, and an ``example`` with a unit for the error message."""

    unit: str
    lo: float
    hi: float
    shown: str
    example: str
    lo_open: bool = False
    integer: bool = False

    def range_text(self) -> str:
        f = parse_unit(self.shown)[0] if self.shown != self.unit else 1.0
        return f"{_num(self.lo / f)}..{_num(self.hi / f)} {self.shown}".rstrip()


def _num(v: float) -> str:
    return f"{v:g}"


def parse(value, quantity: Quantity, name: str) -> float:
    """``value`` (a number, SI; or text: a number with an optional unit) in ``quantity``'s SI
    unit. MagnitudeError (a ValueError) names ``name``, the range and the unit assumed."""
    si_f, si_d = parse_unit(quantity.unit) if quantity.unit not in ("", "-") else (1.0, _d())
    given = None
    if isinstance(value, bool):
        raise MagnitudeError(f"{name} {value!r} is not a magnitude; e.g. {quantity.example}")
    if isinstance(value, (int, float)):
        number = float(value)
    elif isinstance(value, str):
        m = _NUMBER.fullmatch(value)
        if m is None:
            raise MagnitudeError(f"{name} {value.strip()!r} is not a number with a unit; e.g. {quantity.example}")
        number, given = float(m.group(1)), (m.group(2) or None)
    else:
        raise MagnitudeError(f"{name} {value!r} is not a magnitude; e.g. {quantity.example}")
    if given is not None:
        try:
            f, d = parse_unit(given)
        except MagnitudeError as exc:
            raise MagnitudeError(f"{name} {value.strip()!r}: {exc}; e.g. {quantity.example}") from None
        if d != si_d:
            raise MagnitudeError(f"{name} {value.strip()!r}: {given} is not a unit of {quantity.unit or 'a ratio'}; "
                                 f"e.g. {quantity.example}")
        # in decimal: "2.5um" is 2.5e-06 as written, not 2.4999999999999998e-06
        si = float(Decimal(m.group(1)) * Decimal(repr(f)) / Decimal(repr(si_f))) if math.isfinite(number) else number
    else:
        si = number
    if not math.isfinite(si):
        raise MagnitudeError(f"{name} {value!r} must be finite; e.g. {quantity.example}")
    low_ok = si > quantity.lo if quantity.lo_open else si >= quantity.lo
    if not (low_ok and si <= quantity.hi):
        said = f"{_num(number)} {given}" if given else f"{_num(number)} {quantity.unit}".rstrip()
        hint = f"give a unit, e.g. {quantity.example}" if given is None else f"e.g. {quantity.example}"
        above = f" (above {_num(quantity.lo)})" if quantity.lo_open and si == quantity.lo else ""
        raise MagnitudeError(f"{name} {said} is outside {quantity.range_text()}{above}: {hint}")
    if quantity.integer:
        if si != int(si):
            raise MagnitudeError(f"{name} {value!r} must be a whole number of {quantity.unit}")
        return float(int(si))
    return si
