"""Presenters of a ``monitor.audit.AuditResult``: JSON document, text summary, Markdown + PNG report.

Compute, then present: nothing here analyses; it formats the result.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

__all__ = ["to_json", "summary", "write_report", "cause_row"]


def _num(x):
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        x = float(x)
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _num(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_num(v) for v in x]
    return x


def to_json(result) -> dict:
    """The ``audit --json`` document: cause, candidates, gain, params_nominal,
    params_extended (the named cause's model, or the nominal one; with two causes, both
    extensions as fitted together), plus confident/note, and the candidates that could not be
    fitted on the record (``unfitted``: name -> why)."""
    best = result.best
    ext = dict(best.params) if best else dict(result.params_nominal)
    if best:
        ext.update(result.effect or best.effect)
    return _num({
        "cause": result.cause,
        "causes": list(result.causes),
        "verdict": result.words,
        "obeys_model": result.obeys,
        "structure": result.structure,
        "confident": result.confident,
        "note": result.note,
        "candidates": [{"name": c.name, "score": c.score, "twin": c.twin, "gain": c.gain, "value": c.value,
                        "effect": c.effect, "residual_ratio": c.residual_ratio} for c in result.candidates],
        "gain": result.gain,
        "params_nominal": result.params_nominal,
        "params_extended": ext,
        # the smallest Stribeck hump this record would have named [N]: null when not asked (a
        # cause was named, or Stribeck friction was excluded), "beyond" past the largest tried
        "stribeck_reach_N": (None if result.stribeck_reach is None else
                             "beyond" if math.isinf(result.stribeck_reach) else result.stribeck_reach),
        "unfitted": result.unfitted,
        "glitches_replaced": result.glitches,
    })


def glitch_words(glitches: dict) -> str:
    """The sensor glitches replaced before the audit, in words."""
    return ("sensor glitches replaced by their neighbours' mean before the audit: "
            + ", ".join(f"{ch} {n}" for ch, n in glitches.items() if n))


def summary(result) -> str:
    """A few lines for a terminal."""
    lines = [f"cause: {' + '.join(result.causes) or result.cause}" + ("" if result.confident else "  (not confident)")]
    if result.words:
        lines.append(f"verdict: {result.words}")
    if result.note and result.note != result.words:
        lines.append(f"note: {result.note}")
    # score: held-out evidence left once the twin's share (what the candidate scores on the
    # nominal model's twin, a record without any effect) is taken off
    lines.append(f"{'candidate':22s} {'score':>9s} {'twin':>6s} {'free-run gain':>14s}")
    for c in result.candidates:
        lines.append(f"{c.name:22s} {c.score:9.2f} {c.twin:6.2f} {c.gain:14.2f}")
    for name, why in result.unfitted.items():
        lines.append(f"{name:22s} not fitted: {why}")
    if any(result.glitches.values()):
        lines.append(glitch_words(result.glitches))
    g = result.gain
    lines.append("held-out free-run NRMSE (nominal -> extended): " + ", ".join(
        f"{ch} {g[ch]['nrmse_nominal']:.3f} -> {g[ch]['nrmse_extended']:.3f}"
        for ch in ("x1", "x3", "x4", "x5") if ch in g))
    return "\n".join(lines)


def cause_row(result) -> list[str]:
    """``[cause, free-run gain, note]`` of one rig, for the table of a recording's rigs: the cause
    (with its fitted magnitude) and the held-out free-run gain of the extension it names."""
    best = result.best
    cause = result.cause + (f" ({_effect_text(best.effect)})" if best is not None and best.effect else "")
    if not result.confident:
        cause += " (not confident)"
    gain = f"{best.gain:.2f}" if best is not None else "-"
    return [cause, gain, (result.note or "").split(";")[0]]


def _effect_text(effect: dict) -> str:
    return ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in effect.items())


def _md_table(rows, header):
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def write_report(result, directory, what: str = "") -> Path:
    """Write ``audit.md`` and PNG plots (matplotlib, Agg) into ``directory``; returns the Markdown
    path. ``what`` names the record (file and rig) in every plot's title."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    t = result.t
    best = result.best
    names = ("x1 [m]", "x3 [Pa]", "x4 [Pa]", "x5 [m]")
    what = f"{what}: " if what else ""
    if result.simulated_nominal is not None:
        # left: the measured signal and the free runs; right: the free runs' error (measured - simulated)
        fig, axes = plt.subplots(4, 2, figsize=(14, 9), sharex=True)
        extended = best is not None and best.simulated is not None
        for i, (ax, ax_e) in enumerate(axes):
            ax.plot(t, result.measured[:, i], "k", lw=0.8, label="measured")
            ax.plot(t, result.simulated_nominal[:, i], "tab:red", lw=0.8, label="nominal free run")
            ax_e.plot(t, result.measured[:, i] - result.simulated_nominal[:, i], "tab:red", lw=0.8, label="nominal")
            if extended:
                ax.plot(t, best.simulated[:, i], "tab:blue", lw=0.8, label=f"with {best.name}")
                ax_e.plot(t, result.measured[:, i] - best.simulated[:, i], "tab:blue", lw=0.8,
                          label=f"with {best.name}")
            for a in (ax, ax_e):
                a.axvline(t[result.split], color="gray", ls="--", lw=0.8)
                a.grid(alpha=0.3)
            ax_e.axhline(0.0, color="k", lw=0.5)
            ax.set_ylabel(names[i])
            ax_e.set_ylabel(f"error {names[i]}")
        axes[0, 0].set_title(f"{what}measured and free-run signals", fontsize=10)
        axes[0, 1].set_title(f"{what}free-run error (measured - simulated)", fontsize=10)
        axes[0, 0].legend(loc="upper right", fontsize=8)
        axes[0, 1].legend(loc="upper right", fontsize=8)
        for ax in axes[-1]:
            ax.set_xlabel("t [s] (dashed: start of held-out data)")
        fig.tight_layout()
        fig.savefig(d / "freerun.png", dpi=90)
        plt.close(fig)
    blocks = list(result.residuals_nominal.items())
    fig, axes = plt.subplots(len(blocks), 1, figsize=(10, 2.2 * len(blocks)), sharex=True)
    for ax, (g, (rows, r)) in zip(axes, blocks):
        ax.plot(t[rows], r, ".", ms=1, color="tab:red", label="nominal")
        if best is not None:
            br, bres = best.residuals[g]
            ax.plot(t[br], bres, ".", ms=1, color="tab:blue", label=f"with {best.name}")
        ax.set_ylabel(f"{g} residual")
        ax.grid(alpha=0.3)
    axes[0].set_title(f"{what}equation-error residuals (each in its equation's SI unit)", fontsize=10)
    axes[0].legend(loc="upper right", fontsize=8, markerscale=8)
    axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(d / "residuals.png", dpi=90)
    plt.close(fig)

    fr = result.gain
    md = [f"# Model audit\n\n**Cause: {result.cause}**" + ("" if result.confident else " (not confident)"), ""]
    if result.words:
        md += [result.words, ""]
    if result.note and result.note != result.words:
        md += [result.note, ""]
    if any(result.glitches.values()):
        md += [glitch_words(result.glitches) + ".", ""]
    md += ["## Candidates (held-out score, higher is better; free-run gain = error reduction)", "",
           _md_table([(c.name, f"{c.score:.2f}", f"{c.twin:.2f}", f"{c.gain:.2f}",
                       _effect_text(c.effect),
                       c.equation.replace("|", "\\|"))
                      for c in result.candidates], ["name", "score", "twin", "gain", "fitted", "equation"]), ""]
    md += [f"Not fitted: {name}: {why}." for name, why in result.unfitted.items()] + ([""] if result.unfitted else [])
    md += ["## Free run on held-out data", "",
           _md_table([(ch, f"{fr[ch]['nrmse_nominal']:.3f}", f"{fr[ch]['nrmse_extended']:.3f}",
                       f"{fr[ch]['fit_nominal']:.1f}", f"{fr[ch]['fit_extended']:.1f}")
                      for ch in ("x1", "x3", "x4", "x5") if ch in fr],
                     ["channel", "NRMSE nominal", "NRMSE extended", "fit % nominal", "fit % extended"]), "",
           "![free run](freerun.png)", ""]
    md += ["## Equation-error residuals (held-out variance)", "",
           _md_table([(g, f"{v['nominal']:.3g}", f"{v['extended']:.3g}")
                      for g, v in fr["residual_variance"].items()], ["equation", "nominal", "extended"]), "",
           "![residuals](residuals.png)", ""]
    md += ["## Identified parameters (SI)", "",
           _md_table([(k, f"{v:.4g}", f"{best.params[k]:.4g}" if best else "")
                      for k, v in result.params_nominal.items()],
                     ["name", "nominal", "extended"]), ""]
    path = d / "audit.md"
    path.write_text("\n".join(md))
    return path
