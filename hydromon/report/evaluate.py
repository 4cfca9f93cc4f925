"""An evaluated recording as the ``evaluate --json`` document and as a table for a person."""

from __future__ import annotations

import math

from hydromon.contract import PARAM_NAMES, PARAM_UNITS
from hydromon.engine.evaluate import Evaluation
from hydromon.engine.words import CONFIDENCE_HELP, SE_UNKNOWN, confidence_words, placed, se_text, why_words
from hydromon.store.sampling import RATE_TOL
from monitor.ident_options import IdentOptions
from monitor.identify import V_MIN
from monitor.refine import REFINED

__all__ = ["to_json", "render", "render_many", "why"]


def _num(v: float):
    return float(v) if math.isfinite(v) else None


def _health(ev: Evaluation) -> dict:
    a = ev.assessment
    return {"grade": a.grade, "params": a.params, "param_grades": a.param_grades}


def why(ev: Evaluation) -> list[str]:
    """The parameters that carry the grade, in words with the size of their change
    (``hydromon.engine.words.why_words``)."""
    return why_words(_health(ev), ev.ranges, units=True)


def to_json(ev: Evaluation) -> dict:
    """The ``evaluate --json`` document: grade, level, confidence, status, params, std_errors and
    the record's counts (plus ``refined`` when the refinement ran); non-finite numbers (an
    unidentified parameter's standard error is inf) become null."""
    a = ev.assessment
    out = {
        "grade": a.grade,
        "level": a.level if a.level >= 0 else None,
        "confidence": float(a.confidence),
        "status": ev.status,
        "params": {k: _num(a.params[k]) for k in PARAM_NAMES},
        "std_errors": {k: _num(a.std_errors[k]) for k in PARAM_NAMES},
    }
    out["why"] = why(ev)  # added keys
    if ev.glitches is not None:
        out["glitches_replaced"] = ev.glitches
    out["x1_outside_chambers"] = ev.x1_clamped
    out["units"] = ev.units  # why a reading cannot be in the config's units (None: it can)
    out["frozen"] = ev.frozen  # why the readings are not to be trusted: they stopped changing (None: they did not)
    out["wiring"] = ev.wiring  # why the sensors look wired wrong: a dead channel, exchanged pressures (None: not)
    out["implausible"] = list(a.implausible)  # impossible estimates: the grade is withheld
    rec = ev.recording
    out["gaps"] = {"count": len(rec.restarts), "missing_samples": rec.missing, "rejected_samples": rec.rejected,
                   "duplicate_samples": rec.duplicate, "out_of_order_samples": rec.out_of_order}
    out["timestamp_jitter"] = {"intervals": rec.jitter, "max_s": rec.jitter_max}
    out["config_changes"] = {"count": rec.config_changes, "skipped_samples": rec.skipped}
    out["memory_s"] = ev.memory_s  # None: a growing window
    out["uncalibrated"] = ev.uncalibrated  # why no ranges grade the rig (None: some do)
    if ev.refined is not None:  # present only when --refine ran
        r = ev.refined
        out["refined"] = {"ok": r.ok, "message": r.message,
                          "params": {k: _num(r.params[k]) for k in REFINED},
                          "std_errors": {k: _num(r.std_errors[k]) for k in REFINED},
                          "sensor_noise": r.noise}
    return out


def render(ev: Evaluation, console=None) -> None:
    """Print the evaluation as a readable table (rich)."""
    from rich.console import Console
    from rich.table import Table

    console = console or Console()
    a = ev.assessment
    r = ev.recording
    console.print(f"[bold]{r.source}[/bold]  rig {r.rig}: {len(r.samples)} samples, {r.duration:g} s")
    level = "unknown" if a.level < 0 else str(a.level)
    console.print(f"grade [bold]{a.grade}[/bold]  level {level}  confidence {a.confidence:.3f}  "
                  f"status {ev.status}")
    if ev.uncalibrated is not None:
        console.print(f"[yellow]not graded: {ev.uncalibrated}[/yellow]")
    words = why(ev)
    if words:
        console.print("why: " + "; ".join(words), markup=False)
    if a.param_levels:
        console.print(confidence_words(a.confidence, *placed(a.param_grades)), markup=False)
    if ev.memory_s is not None:  # the default, a growing window, needs no line
        console.print(f"estimators' memory {ev.memory_s:g} s (--memory): data older than that fades")
    t = Table(show_header=True, header_style="bold")
    ref = ev.refined
    cols = [("parameter", "left"), ("value", "right"), ("std error", "right")]
    if ref is not None:
        cols += [("refined", "right"), ("std error ", "right")]
    for col, just in cols + [("unit", "left"), ("grade", "left")]:
        t.add_column(col, justify=just)
    grades = a.param_grades
    for k in PARAM_NAMES:
        row = [k, f"{a.params[k]:.5g}", se_text(a.std_errors[k])]
        if ref is not None:
            row += [f"{ref.params[k]:.5g}", se_text(ref.std_errors[k])] if k in REFINED else ["", ""]
        t.add_row(*row, PARAM_UNITS[k], grades.get(k, ""))
    console.print(t)
    if any(not math.isfinite(a.std_errors[k]) for k in PARAM_NAMES):
        console.print(f"[dim]{SE_UNKNOWN}[/dim]")
    if not a.converged:
        need = (ev.options or IdentOptions()).min_rows
        head = (f"not converged: the chamber and valve equations need {need} rows each before a grade (about "
                f"{need / r.config.sample_rate:g} s of samples after the filters' warm-up); this record has "
                f"{len(r.samples)} samples")
        gaps = f" and {len(r.restarts)} gap(s), after each of which the filters warm up again" if r.restarts else ""
        if len(r.samples) < 3 * need:  # most often the reason: too short a record
            console.print(f"[yellow]{head}{gaps}: give a longer one[/yellow]")
        else:  # long enough: the rows the equations take need motion, and stretches without gaps
            console.print(f"[yellow]{head}{gaps}, which would be enough: what it lacks is motion (a command that "
                          "moves the valve and the piston: a constant or zero one gives the equations no rows)"
                          + (" or stretches without gaps" if gaps else "") + "[/yellow]")
    if r.config_changes:
        console.print(f"[yellow]the rig's config changed {r.config_changes} time(s): evaluated the samples after the "
                      f"last change (sample {r.skipped}, t = {r.t[0]:g} s) with its constants, as the live monitor "
                      f"restarts a rig's estimates there; the {r.skipped} sample(s) before it were skipped "
                      "(hydromon replay --direct grades every stretch)[/yellow]")
    if r.restarts or r.rejected or r.duplicate or r.out_of_order:
        dropped = (f", {r.duplicate} duplicate and {r.out_of_order} out-of-order sample(s) dropped (seq not above "
                   "the last one taken)" if r.duplicate or r.out_of_order else "")
        console.print(f"[yellow]{len(r.restarts)} gap(s), {r.missing} sample(s) missing, {r.rejected} invalid "
                      f"sample(s) skipped{dropped}: the filters restarted after each gap, the estimates carried "
                      "on[/yellow]")
    if r.jitter:
        console.print(f"[yellow]{r.jitter} sample interval(s) with time stamps off their seq step by more than "
                      f"{100 * RATE_TOL:g} % of a period (largest {1e3 * r.jitter_max:.3g} ms): graded by seq, as "
                      "the live monitor does[/yellow]")
    if a.implausible:
        what = ", ".join(f"{k} = {a.params[k]:.3g} (SE {a.std_errors[k]:.2g})" for k in a.implausible)
        console.print(f"[red]not graded: physically impossible estimates ({what}; each must be positive). The "
                      "record does not obey the model: check the units (SI: m, Pa, V), the signs and zeros of x1, "
                      "x3, x4, x5 and ug, and the rig constants[/red]")
    if ev.units:
        console.print(f"[red]not to be trusted: {ev.units}[/red]", highlight=False)
    if ev.frozen:
        console.print(f"[red]not to be trusted: {ev.frozen}[/red]", highlight=False)
    if ev.wiring:
        console.print(f"[red]not to be trusted: {ev.wiring}[/red]", highlight=False)
    if ev.x1_clamped:
        c = r.config
        lo, hi = -(1 - V_MIN) * c.V10 / c.A1, (1 - V_MIN) * c.V20 / c.A2
        console.print(f"[red]{ev.x1_clamped} sample(s) put x1 at a chamber's end (x1 < {lo:.4g} m or > {hi:.4g} m "
                      "leaves a chamber under 1 % of its volume V_i0): the rig constants or x1's zero, sign or "
                      "unit are wrong, and the chamber parameters are not to be trusted[/red]")
    if ev.glitches and any(ev.glitches.values()):
        what = ", ".join(f"{n} {k}" for k, n in ev.glitches.items() if n)
        console.print(f"[yellow]sensor glitches replaced by their neighbours' mean: {what}[/yellow]")
    if ref is not None:
        console.print(f"refined: whole-record prediction-error fit, {'ok' if ref.ok else 'FAILED'}: {ref.message}; "
                      "the grade is the streaming pipeline's")


def render_many(evs: dict, errors: dict, source: str, console=None) -> None:
    """Every rig of a recording: one row each, the rigs that need attention first (bad input,
    then the worst grade), with why in words; ``errors`` the rigs that could not be evaluated."""
    from rich.console import Console
    from rich.table import Table

    console = console or Console()
    n = len(evs) + len(errors)
    console.print(f"[bold]{source}[/bold]  {n} rigs", markup=True)
    t = Table(show_header=True, header_style="bold")
    for col, just in (("rig", "left"), ("grade", "left"), ("conf", "right"), ("status", "left"),
                      ("samples", "right"), ("why", "left")):
        t.add_column(col, justify=just)

    def order(item):
        rig, ev = item
        return (ev.status != "bad-input", ev.status != "uncalibrated", -ev.assessment.level, rig)

    for rig, ev in sorted(evs.items(), key=order):
        a = ev.assessment
        t.add_row(rig, a.grade, f"{a.confidence:.2f}", ev.status, str(len(ev.recording.samples)),
                  "; ".join(why(ev)) or "-")
    for rig, message in sorted(errors.items()):
        t.add_row(rig, "-", "-", "not evaluated", "-", message)
    console.print(t)
    console.print(f"[dim]{CONFIDENCE_HELP}; one rig in full: hydromon evaluate {source} --rig ID[/dim]")
    if any(ev.uncalibrated for ev in evs.values()):
        console.print("[yellow]uncalibrated: no ranges were made for the rig's constants, so it is not graded; "
                      f"hydromon evaluate {source} --rig ID says why[/yellow]")
