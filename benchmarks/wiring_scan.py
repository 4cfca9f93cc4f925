"""The exchanged-pressure check (monitor.audit.wiring) on the audit's records: each record as it
is (a call is a false alarm) and with x3 and x4 exchanged (a call is a detection), clean and with
each effect at its largest magnitude; every input shape, health band, reference and random rigs,
no, realistic and stress noise, 20 s. Prints the counts per effect and the records nearest to a
false alarm (the smaller of the two log factors by which the exchange lowers the residuals; a
call also needs the exchanged fit possible).
Run: python benchmarks/wiring_scan.py --seed-base 21500000 [--repeats 1] [--effects]
"""
from __future__ import annotations

from hydromon.tools import jitcache

jitcache.configure()  # before any kernel is imported

import argparse
import itertools

from hydromon.tools.audit_cases import BANDS, PROFILES, _drawn, _record, largest_effect_sets
from monitor.audit.wiring import exchange

NOISES = ("none", "realistic", "stress")


def _scan(effects: dict, base: int, repeats: int) -> tuple[int, int, str, list]:
    """(records, false alarms, detections per noise level in words, [(margin, label)]) over one
    effect set."""
    n = alarms = 0
    found = {noise: [0, 0] for noise in NOISES}  # exchanged copies named, records
    near = []
    cells = itertools.product(("ref", "rig"), PROFILES, BANDS, NOISES, range(repeats))
    for i, (kind, profile, band, noise, _) in enumerate(cells):
        seed = base + i
        p, sev = _drawn(profile, band, seed)
        x, cfg = _record(kind, effects, p, sev, noise, seed)
        as_is, other = exchange(x, cfg), exchange(x[:, [0, 1, 3, 2, 4]], cfg)
        if as_is is None or other is None:
            continue
        n += 1
        alarms += as_is.called
        found[noise][0] += other.called
        found[noise][1] += 1
        near.append((min(as_is.chamber, as_is.force), f"{kind} {profile} severity {sev:.2f} {noise} seed {seed}"))
    named = sum(f[0] for f in found.values())
    words = f"{named} ({', '.join(f'{noise} {f[0]}/{f[1]}' for noise, f in found.items())})"
    return n, alarms, words, sorted(near, reverse=True)[:2]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed-base", type=int, required=True)
    ap.add_argument("--repeats", type=int, default=1, help="records per cell (default 1: 120 records per effect set)")
    ap.add_argument("--effects", action="store_true", help="also each effect at its largest magnitude")
    a = ap.parse_args()
    sets = largest_effect_sets(a.effects)
    print(f"{'records':20s} {'n':>5s} {'false alarms':>13s}  {'exchanged copies named':44s}  "
          "nearest to a false alarm (log)")
    for k, (label, effects) in enumerate(sets):
        n, alarms, found, near = _scan(effects, a.seed_base + 1000 * k, a.repeats)
        print(f"{label:20s} {n:5d} {alarms:13d}  {found:44s}  " + "; ".join(f"{m:+.2f} {w}" for m, w in near),
              flush=True)


if __name__ == "__main__":
    main()
