"""The ``--memory`` option that monitor, evaluate and replay --direct share (one text, one parse)."""

from __future__ import annotations

import math

MIN_MEMORY_S = 10.0  # [s] the estimators need a few seconds of rows (min_rows 300 at 100 Hz) inside it

LIVE_MEMORY_S = 60.0
"""[s] The live monitor's default memory: the one of 60, 120, 300, 600 s and a growing window
that follows a one-grade step of K_sv, f_c and both leakages within a 900 s run at realistic
noise (``python benchmarks/memory_tradeoff.py``; the table in docs/method.md), at no cost in
grades on rigs that do not change."""

MEMORY_HELP = ("the estimators' memory in seconds, or a time with its unit (90, 2min): older data fades "
               "(forgetting factor exp(-1/(S x rate))), so a rig that degrades while watched is followed within "
               "a few S (docs/method.md has the measured times and what a memory costs); none: a growing window, "
               f"which keeps everything and is blind to a change late in a long run; at least {MIN_MEMORY_S:g}")


GROWING = ("none", "inf", "growing")
"""What ``--memory`` takes for a growing window (the estimators keep everything)."""


def add_memory_argument(parser, help: str, default: float | None = None) -> None:
    """``--memory S`` with ``help`` (say the default in it); ``default`` [s] or None (growing)."""
    parser.add_argument("--memory", default=default, metavar="S", help=help)


def check_memory(args) -> None:
    """Read ``--memory`` into seconds (None: a growing window) in ``args.memory``: a number of
    seconds or a time with its unit (``90``, ``2min``), or ``none``; under MIN_MEMORY_S (or
    not finite) it is a ValueError naming it."""
    m = args.memory
    if isinstance(m, str):
        if m.strip().lower() in GROWING:
            args.memory = None
            return
        from hydromon.store.magnitudes import parse
        from hydromon.store.quantities import MEMORY

        try:
            m = parse(m, MEMORY, "--memory")
        except ValueError as exc:
            raise ValueError(f"{exc}, or none") from None
    if m is not None and not (math.isfinite(m) and m >= MIN_MEMORY_S):
        raise ValueError(f"--memory {m!r} s: at least {MIN_MEMORY_S:g} s (the estimators need a few seconds of "
                         "rows inside their memory), or none (a growing window)")
    args.memory = m


def options_from_args(args, sample_rate: float):
    """``monitor.ident_options.IdentOptions`` with the forgetting factor of ``--memory`` at
    ``sample_rate`` [Hz] (None for a growing window: the defaults, no forgetting)."""
    check_memory(args)
    if args.memory is None:
        return None
    from monitor.ident_options import IdentOptions

    return IdentOptions(lam=math.exp(-1.0 / (args.memory * sample_rate)))
