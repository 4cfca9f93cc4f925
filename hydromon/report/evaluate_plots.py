"""``evaluate --plots DIR``: an evaluated recording as three PNGs (matplotlib, files only).

* ``<stem>-grade.png``: the fused grade over time with its confidence, and every graded
  parameter's own grade below it (grey: unknown), so a change of grade shows which
  parameter moved it;
* ``<stem>-params.png``: each graded parameter's estimate over time with its +-3
  standard-error band against its health bands, drawn as coloured, labelled zones, and the
  refined value when there is one; ``<stem>-params-other.png``: the other parameters alike,
  without bands;
* ``<stem>-signals.png``: the recorded signals with the glitches the outlier gate replaced
  marked, and the gaps.

:func:`plot_evaluation` returns what it drew (files, and counts a test can hold against the
evaluation), so the plots are checked, not just written.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hydromon.contract import GRADES, PARAM_NAMES, PARAM_UNITS, PARAM_WORDS
from hydromon.report.zones import GRADE_COLOURS, draw_zones
from monitor.outlier_gate import gated

__all__ = ["PlotSummary", "plot_evaluation"]

_SENSORS = ("x1", "x3", "x4", "x5")
_GRADE_COLOURS = tuple(GRADE_COLOURS[g] for g in GRADES)


@dataclass(frozen=True)
class PlotSummary:
    """What :func:`plot_evaluation` drew: the files, the evaluations on the time axis, and the
    glitch markers per sensor (equal to the evaluation's ``glitches`` when the gate matches)."""

    files: list[Path]
    evaluations: int
    glitch_markers: dict[str, int]
    gaps: int


def plot_evaluation(ev, directory: str | Path, stem: str | None = None) -> PlotSummary:
    """Write the four PNGs of an :class:`hydromon.engine.evaluate.Evaluation` into ``directory``
    (created if missing); ``stem`` defaults to the recording's file stem and rig."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if ev.history is None:
        raise ValueError("this evaluation has no history to plot (evaluate() keeps it)")
    rec, h = ev.recording, ev.history
    out = Path(directory)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"plots directory {str(directory)!r}: {exc.strerror or exc}") from None
    stem = stem or f"{Path(rec.source).stem}-{rec.rig}"
    where = f"{Path(rec.source).name}, rig {rec.rig}"
    t_ev = rec.t[h.sample] if len(h) else np.empty(0)
    t_gap = [rec.t[i] for i in rec.restarts]
    files = []

    def save(fig, name):
        fig.tight_layout()
        path = out / f"{stem}-{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        files.append(path)

    def mark_gaps(ax):
        for tg in t_gap:
            ax.axvline(tg, color="k", ls=":", lw=0.8)

    # grade: the fused level (unknown = -1) and confidence; per-parameter grades as a strip
    bands = ev.ranges.params if ev.ranges is not None else {}  # none: the rig is not graded
    graded = tuple(n for n in PARAM_NAMES if n in bands)
    fig, (ax, ax_p) = plt.subplots(2, 1, figsize=(9, 3.2 + 0.35 * len(graded)), sharex=True,
                                   gridspec_kw={"height_ratios": [3, max(1, len(graded))]})
    ax.step(t_ev, h.level, where="post", color="tab:blue", lw=1.5, label="grade")
    ax.set_yticks(range(-1, len(GRADES)), ("unknown",) + GRADES)
    ax.set_ylim(-1.5, len(GRADES) - 0.5)
    ax.grid(alpha=0.3)
    axc = ax.twinx()
    axc.plot(t_ev, h.confidence, color="tab:gray", lw=0.8, label="confidence")
    axc.set_ylim(0, 1.05)
    axc.set_ylabel("confidence")
    mark_gaps(ax)
    ax.set_title(f"{Path(rec.source).name}, rig {rec.rig}: final grade {ev.assessment.grade} "
                 f"(confidence {ev.assessment.confidence:.2f})")
    if not graded:
        ax_p.text(0.5, 0.5, "not graded: no ranges made for this rig", transform=ax_p.transAxes, ha="center",
                  va="center", fontsize=8)
    elif len(h):
        colours = np.array([(0.8, 0.8, 0.8)] + [matplotlib.colors.to_rgb(c) for c in _GRADE_COLOURS])
        img = colours[h.grades.T + 1]  # (graded, events, rgb); unknown (-1) grey
        edges = np.r_[t_ev, t_ev[-1] + (t_ev[-1] - t_ev[-2] if len(t_ev) > 1 else 1.0)]
        ax_p.imshow(img, aspect="auto", interpolation="nearest",
                    extent=(edges[0], edges[-1], len(graded), 0))
        ax_p.set_ylim(len(graded), 0)
    ax_p.set_yticks(np.arange(len(graded)) + 0.5, graded)
    ax_p.set_ylabel("grade of each graded parameter", fontsize=8)
    ax.set_ylabel("grade")
    ax_p.set_xlabel(f"t [s], rig {rec.rig}")
    handles = [matplotlib.patches.Patch(color=c, label=g) for c, g in zip(_GRADE_COLOURS, GRADES)]
    handles.append(matplotlib.patches.Patch(color=(0.8, 0.8, 0.8), label="unknown"))
    ax_p.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    mark_gaps(ax_p)
    save(fig, "grade")

    # params: estimate +- 3 SE against the health bands (graded), then the others; a rig with no
    # ranges made for it has every parameter in the one figure, said to be not graded
    graded_names = [k for k in PARAM_NAMES if k in bands]
    other_names = [k for k in PARAM_NAMES if k not in bands]
    if graded_names:
        save(_param_figure(plt, ev, h, t_ev, graded_names, bands, mark_gaps,
                           f"{where}: graded parameters (band: +-3 standard errors; zones: health bands)"), "params")
    if other_names:
        save(_param_figure(plt, ev, h, t_ev, other_names, bands, mark_gaps,
                           f"{where}: {'other parameters, ' if graded_names else ''}not graded "
                           "(band: +-3 standard errors)"), "params-other" if graded_names else "params")

    # signals, with the glitches the gate replaced
    g, _ = gated(rec.samples, ev.options, restarts=rec.restarts)
    replaced = g != rec.samples
    markers = {}
    fig, axes = plt.subplots(4, 1, figsize=(9, 8), sharex=True)
    panels = (("ug [V]", (0,)), ("x1 [mm]", (1,)), ("x3, x4 [MPa]", (2, 3)), ("x5 [um]", (4,)))
    scale = (1.0, 1e3, 1e-6, 1e-6, 1e6)
    for axj, (label, cols) in zip(axes, panels):
        for c in cols:
            axj.plot(rec.t, rec.samples[:, c] * scale[c], lw=0.7, label=("ug", "x1", "x3", "x4", "x5")[c])
            if c:
                idx = np.flatnonzero(replaced[:, c])
                markers[_SENSORS[c - 1]] = len(idx)
                if len(idx):
                    axj.plot(rec.t[idx], rec.samples[idx, c] * scale[c], "rx", ms=6,
                             label=f"{len(idx)} glitch(es) replaced")
        axj.set_ylabel(label, fontsize=8)
        axj.grid(alpha=0.3)
        axj.legend(loc="upper right", fontsize=7)
        mark_gaps(axj)
    axes[0].set_title(f"{where}: recorded signals ({len(rec.restarts)} gap(s) dotted)")
    axes[-1].set_xlabel("t [s]")
    save(fig, "signals")
    return PlotSummary(files, len(h), markers, len(rec.restarts))


def _param_figure(plt, ev, h, t_ev, names, bands, mark_gaps, title):
    """One panel per parameter of ``names``: the estimate, its +-3 SE band, the health bands of a
    graded one (``bands``: name -> its health bands) as zones, the refined value; the view is the run's last fifth and the nearest edges."""
    fig, axes = plt.subplots(len(names), 1, figsize=(9, 0.6 + 1.8 * len(names)), sharex=True, squeeze=False)
    axes = axes[:, 0]
    for axj, k in zip(axes, names):
        j = PARAM_NAMES.index(k)
        p, s = h.params[:, j], h.std_errors[:, j]
        ok = np.isfinite(p) & np.isfinite(s)
        axj.plot(t_ev, np.where(np.isfinite(p), p, np.nan), color="tab:blue", lw=1.1, label="estimate", zorder=3)
        axj.fill_between(t_ev, np.where(ok, p - 3 * s, np.nan), np.where(ok, p + 3 * s, np.nan),
                         color="tab:blue", alpha=0.2, lw=0, zorder=2)
        final = ev.assessment.params[k]
        if ev.refined is not None and k in ev.refined.params and np.isfinite(ev.refined.params[k]):
            axj.axhline(ev.refined.params[k], color="tab:green", lw=1.0, ls="-.", label="refined", zorder=3)
            axj.legend(loc="upper left", fontsize=7)
        if np.isfinite(final) and final != 0.0:
            # the view: the last fifth of the run +- 4 SE, and the edges of the band it is in
            tail, sd = (p[ok][-max(1, ok.sum() // 5):], s[ok][-max(1, ok.sum() // 5):]) if ok.any() \
                else (np.array([final]), np.array([0.0]))
            lo, hi = np.min(tail - 4 * sd), np.max(tail + 4 * sd)
            if k in bands:
                e = bands[k].edge_array()
                below, above = e[e <= final], e[e > final]
                lo = min(lo, below.max()) if below.size else lo
                hi = max(hi, above.min()) if above.size else hi
            pad = max(hi - lo, 0.02 * abs(final))
            axj.set_ylim(lo - 0.15 * pad, hi + 0.15 * pad)
        if k in bands:
            draw_zones(axj, bands[k])
        axj.set_ylabel(f"{k} [{PARAM_UNITS[k]}]", fontsize=8)
        axj.set_title(f"rig {ev.recording.rig}: {PARAM_WORDS[k]}", fontsize=8, loc="left")
        axj.grid(alpha=0.3)
        mark_gaps(axj)
    fig.suptitle(title, fontsize=10)
    axes[-1].set_xlabel("t [s]")
    return fig
