"""The audit sweep's tables (``hydromon.tools.audit_sweep``), printed as Markdown for
``docs/audit.md``: per effect and step, per ladder rung, per clean noise level, per pair."""

from __future__ import annotations

from functools import partial

from .audit_cases import BANDS, CLAIMS, CLEAN_NOISES, CLEAN_SEED, LADDER, LADDER_SEED, NOISES, PAIR_SEED, PAIRS, \
    PROFILES, RIG_MULTIPLE, RIG_SEED, STEPS


def _right(results, i) -> bool:
    """Whether record ``i`` was named what it holds."""
    return results[i][0] == results[i][1]


def _profile_cells(results, right, in_row, columns=PROFILES) -> str:
    """A table row's cells: records named right of those ``in_row(i, column)`` holds, per column
    (a profile unless ``columns`` says otherwise), then all."""
    cells, tot, n = [], 0, 0
    for p in columns:
        idx = [i for i in results if in_row(i, p)]
        k = sum(right(i) for i in idx)
        cells.append(f"{k}/{len(idx)}" if idx else "-")
        tot, n = tot + k, n + len(idx)
    return " | ".join(cells) + f" | {tot}/{n} |"


def _print_listed(title, indices, cases, results, describe):
    """The records of ``indices`` and what each was named, ``describe(case)`` saying which record."""
    if indices:
        print(f"\n{title} (index: record -> named):")
        for i in indices:
            print(f"- {i}: {describe(*cases[i])} -> {', '.join(results[i][0])}  ({results[i][3]})")


def _print_wrong(cases, results, describe):
    """Every record named other than what it holds (``_print_listed``)."""
    _print_listed("Wrong answers", [i for i in sorted(results) if not _right(results, i)], cases, results, describe)


def _print_tables(cases, results, seeds, base, wall, duration):
    right = partial(_right, results)
    print(f"Audit sweep, seeds '{seeds}' (base {base}), {len(results)} records of {duration:g} s, "
          f"{wall:.0f} s wall.\n")
    print("One effect, named right per profile (of the two noise levels' records at that step):\n")
    print("| effect | unit | claimed limit none / realistic | step | " + " | ".join(PROFILES) + " | all |")
    print("|---|---|---|---|" + "---|" * (len(PROFILES) + 1))
    for name, (unit, lim, large, _) in CLAIMS.items():
        for step in STEPS:
            row = _profile_cells(results, right, lambda i, p: cases[i][0] == "one" and name in cases[i][1]
                                 and cases[i][2] == p and cases[i][5] == step)
            print(f"| {name} | {unit} | {lim['none']:g} / {lim['realistic']:g} | {step} | " + row)
    for kind, label in (("one", "one effect, all"), ("clean", "clean (named 'none')"),
                        ("pair", "two effects (both named)"), ("outside", "outside the library ('unexplained')")):
        idx = [i for i in results if cases[i][0] == kind]
        if not idx:
            continue
        by_noise = {}
        for i in idx:
            by_noise.setdefault(cases[i][4], []).append(right(i))
        parts = ", ".join(f"{nz} {sum(v)}/{len(v)}" for nz, v in by_noise.items())
        print(f"\n{label}: {sum(right(i) for i in idx)}/{len(idx)} right ({parts})")
    clean_named = [i for i in results if cases[i][0] == "clean" and results[i][0] != ["none"]]
    print(f"clean records named as an effect or unexplained: {len(clean_named)}")
    _print_wrong(cases, results, lambda kind, effects, profile, severity, noise, step:
                 f"{kind} {effects} {profile} severity {severity} {noise} {step}")


def _print_ladder(name, cases, results, base, wall, duration):
    unit = CLAIMS[name][0]
    print(f"Ladder of {name}, base {base} (seeds base + {LADDER_SEED} + index), {len(results)} records of "
          f"{duration:g} s, {wall:.0f} s wall. Each cell: records named right of the five bands' records.\n")
    print(f"| noise | {name} [{unit}] | multiple of the claimed limit | " + " | ".join(PROFILES) + " | all |")
    print("|---|---|---|" + "---|" * (len(PROFILES) + 1))
    right = partial(_right, results)
    for noise in NOISES:
        for f in LADDER:
            row = _profile_cells(results, right, lambda i, p: cases[i][4] == noise
                                 and cases[i][5] == f"{f}x limit" and cases[i][2] == p)
            print(f"| {noise} | {CLAIMS[name][1][noise] * f:g} | {f} | " + row)
    _print_wrong(cases, results, lambda kind, effects, profile, severity, noise, step:
                 f"{effects} {profile} severity {severity} {noise}")


def _print_clean(cases, results, base, wall, duration, noises=CLEAN_NOISES):
    print(f"Clean records, base {base} (seeds base + {CLEAN_SEED} + index), {len(results)} records of "
          f"{duration:g} s, {wall:.0f} s wall.\n")
    print("| noise | named none | named an effect | unexplained | refused |")
    print("|---|---|---|---|---|")
    for noise in noises:
        got = [results[i][0] for i in results if cases[i][4] == noise]
        named = sum(g not in (["none"], ["unexplained"], ["refused"]) for g in got)
        print(f"| {noise} | {got.count(['none'])}/{len(got)} | {named} | {got.count(['unexplained'])} | "
              f"{got.count(['refused'])} |")
    _print_listed("Not none", [i for i in sorted(results) if results[i][0] != ["none"]], cases, results,
                  lambda kind, effects, profile, severity, noise, step:
                  f"{profile} severity {severity} {noise} {step}")


def _print_pairs(cases, results, base, wall, duration):
    print(f"Two-effect records, base {base} (seeds base + {PAIR_SEED} + index), {len(results)} records of "
          f"{duration:g} s at realistic noise, {wall:.0f} s wall. Each cell: records with both effects named.\n")
    right = partial(_right, results)
    pairs = [{a: va, b: vb} for a, va, b, vb in PAIRS]
    for by, values, at in (("profile", PROFILES, 2), ("health band (severity at its centre)", BANDS, 3)):
        print(f"By {by}:\n")
        print("| pair | " + " | ".join(str(v) for v in values) + " | all |")
        print("|---|" + "---|" * (len(values) + 1))
        for pair in pairs:
            row = _profile_cells(results, right, lambda i, v: cases[i][1] == pair and cases[i][at] == v, values)
            print(f"| {' + '.join(f'{k} {v:g}' for k, v in pair.items())} | " + row)
        print()
    print(f"two effects (both named): {sum(right(i) for i in results)}/{len(results)} right")
    _print_wrong(cases, results, lambda kind, effects, profile, severity, noise, step:
                 f"{effects} {profile} severity {severity}")


def _print_rigs(cases, results, base, wall, duration):
    print(f"Records on rigs of their own, base {base} (seeds base + {RIG_SEED} + index), {len(results)} records of "
          f"{duration:g} s, {wall:.0f} s wall. Each effect at {RIG_MULTIPLE} times its claimed limit, scaled to "
          f"the rig. Each cell: records named right of the five bands' records.\n")
    print("| noise | record | magnitude on the reference rig | " + " | ".join(PROFILES) + " | all |")
    print("|---|---|---|" + "---|" * (len(PROFILES) + 1))
    right = partial(_right, results)
    for noise in NOISES:
        for name in (None, *CLAIMS):
            what = (lambda e: not e) if name is None else (lambda e: name in e)
            row = _profile_cells(results, right, lambda i, p: cases[i][4] == noise and what(cases[i][1])
                                 and cases[i][2] == p)
            size = "-" if name is None else f"{RIG_MULTIPLE * CLAIMS[name][1][noise]:g} {CLAIMS[name][0]}"
            print(f"| {noise} | {name or 'clean'} | {size} | " + row)
    for label, sel in (("one effect", lambda e: bool(e)), ("clean (named 'none')", lambda e: not e)):
        idx = [i for i in results if sel(cases[i][1])]
        print(f"\n{label}: {sum(right(i) for i in idx)}/{len(idx)} right")
    _print_wrong(cases, results, lambda kind, effects, profile, severity, noise, step:
                 f"{effects or 'clean'} {profile} severity {severity} {noise}")
