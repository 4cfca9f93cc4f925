"""False calls of the stuck-pressure watch (hydromon.engine.stuck_watch) on right records: the
audit's records (20 s, every input shape and health band, reference and random rigs, no,
realistic and stress noise), clean and with each effect at its largest magnitude, with the
pressures and the spool on the grids given (a coarse transducer repeats its reading). Prints the
records called per effect set (false calls), the longest held pressure under a moving spool, and
how many of the same records were called once x3 is held from 5 s on (a stuck sensor found).
Run: python benchmarks/stuck_scan.py --seed-base 21800000 [--grid-pa 10000] [--grid-x5 5e-7] [--effects]
"""
from __future__ import annotations

from hydromon.tools import jitcache

jitcache.configure()  # before any kernel is imported

import argparse
import itertools

import numpy as np

from hydromon.engine.stuck_watch import _one_row_runs, stuck_words
from hydromon.tools.audit_cases import BANDS, PROFILES, _drawn, _record, largest_effect_sets
from monitor.audit.wiring import SPOOL_MOVES

NOISES = ("none", "realistic", "stress")


def _longest(s: np.ndarray, rate: float, moves: float) -> float:
    """The longest stretch [s] a pressure of ``s`` holds one reading under a spool that travels
    more than ``moves`` [m] (the watch with a one-sample threshold, each channel read at every
    sample)."""
    longest = 0
    for b in _one_row_runs(s, moves, 1):
        hit = np.flatnonzero(b >= 0)
        longest = max(longest, int((hit - b[hit]).max(initial=0)))
    return longest / rate


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed-base", type=int, required=True)
    ap.add_argument("--grid-pa", type=float, default=1e4, help="pressure grid [Pa] (0: as simulated)")
    ap.add_argument("--grid-x5", type=float, default=5e-7, help="spool grid [m] (0: as simulated)")
    ap.add_argument("--effects", action="store_true", help="also each effect at its largest magnitude")
    a = ap.parse_args()
    sets = largest_effect_sets(a.effects)
    print(f"{'records':24s} {'n':>5s} {'called':>7s} {'stuck found':>12s}  "
          "longest held pressure under a moving spool [s]")
    for k, (label, effects) in enumerate(sets):
        n = called = found = 0
        longest = 0.0
        cells = itertools.product(("ref", "rig"), PROFILES, BANDS, NOISES)
        for i, (kind, profile, band, noise) in enumerate(cells):
            seed = a.seed_base + 1000 * k + i
            p, sev = _drawn(profile, band, seed)
            s, cfg = _record(kind, effects, p, sev, noise, seed)
            if a.grid_pa:
                s[:, 2:4] = np.round(s[:, 2:4] / a.grid_pa) * a.grid_pa
            if a.grid_x5:
                s[:, 4] = np.round(s[:, 4] / a.grid_x5) * a.grid_x5
            n += 1
            called += stuck_words(s, cfg.sample_rate, cfg.x5_span) is not None
            longest = max(longest, _longest(s, cfg.sample_rate, SPOOL_MOVES * cfg.x5_span))
            held = int(5.0 * cfg.sample_rate)
            s[held:, 2] = s[held, 2]
            found += stuck_words(s, cfg.sample_rate, cfg.x5_span) is not None
        print(f"{label:24s} {n:5d} {called:7d} {found:12d}  {longest:.2f}", flush=True)


if __name__ == "__main__":
    main()
