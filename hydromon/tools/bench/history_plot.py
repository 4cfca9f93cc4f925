"""The benchmark history (``benchmarks/history.jsonl``, one ``hydromon bench --json`` document a
line) drawn as one PNG, so a regression shows at a glance: throughputs against their targets,
live rigs against the transport ceiling, live as a share of the ceiling, and the monitor's CPU per
sample against the kernel's."""

from __future__ import annotations

import json

# the performance targets [samples/s; rigs at 100 Hz; share of the ceiling] (docs/performance.md)
TARGETS = {"core_single": 1e5, "core_batch": 1e6, "replay_direct": 1e5, "replay_direct_framed": 8e5}
LIVE_TARGET_RIGS = 1000
LIVE_FRAMED_TARGET_RIGS = 3000  # live with frames of 10
MONITOR_KERNEL_RATIO_TARGET = 2.0  # monitor_us_per_sample at most this many kernel_us_per_sample
CEILING_SHARE_TARGET = 0.5
SAMPLE_RATE = 100.0  # [Hz] a live rig's samples per second

__all__ = ["load_history", "history_figure"]


def load_history(path) -> list[dict]:
    """The runs of a history file, in file order; a line that is not a JSON object is an error
    naming file and line (a half-written last line from a killed run included)."""
    runs = []
    with open(path, encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            if not line.strip():
                continue
            try:
                doc = json.loads(line)
            except ValueError as exc:
                raise ValueError(f"{path}:{n}: not a JSON document ({exc})") from None
            if not isinstance(doc, dict):
                raise ValueError(f"{path}:{n}: not a bench run (a JSON object)")
            runs.append(doc)
    if not runs:
        raise ValueError(f"{path}: no runs in it")
    return runs


def _num(v):
    return float(v) if isinstance(v, (int, float)) and v == v else None


def history_figure(runs: list[dict]):
    """A matplotlib Figure of the runs (x: run in file order, labelled by its UTC time).
    Runs made with ``--quick`` are drawn hollow: smaller sizes, rougher figures."""
    from matplotlib.figure import Figure

    x = list(range(len(runs)))
    quick = [bool((r.get("details") or {}).get("quick")) for r in runs]
    fig = Figure(figsize=(max(8.0, 0.45 * len(runs) + 3), 13.0), layout="constrained")
    ax_t, ax_l, ax_s, ax_u = fig.subplots(4, 1, sharex=True)

    def points(ax, ys, label, color, marker="o"):
        full = [(i, y) for i, y, q in zip(x, ys, quick) if y is not None and not q]
        rough = [(i, y) for i, y, q in zip(x, ys, quick) if y is not None and q]
        ax.plot([i for i, y in zip(x, ys) if y is not None], [y for y in ys if y is not None], "-", color=color,
                alpha=0.35, lw=1)
        if full:
            ax.plot(*zip(*full), marker, color=color, label=label)
        if rough:
            ax.plot(*zip(*rough), marker, color=color, mfc="none", label=f"{label} (--quick)")

    colors = {"core_single": "C0", "core_batch": "C1", "replay_direct": "C2", "replay_direct_framed": "C5",
              "replay_direct_framed_jobs": "C6", "baseline_naive": "C7"}
    for key, color in colors.items():
        points(ax_t, [_num(r.get(key)) for r in runs], key, color)
        if key in TARGETS:
            ax_t.axhline(TARGETS[key], color=color, ls="--", lw=1)
    ax_t.set_yscale("log")
    ax_t.set_ylabel("samples/s (dashed: targets)")
    ax_t.set_title("hydromon bench history: throughput")
    ax_t.legend(fontsize=8, ncol=2, loc="lower right")

    # one monitor's runs and sharded runs (hydromon bench --monitors K) are separate series
    sharded = [((r.get("live") or {}).get("monitors") or 1) > 1 for r in runs]
    all_live = [_num((r.get("live") or {}).get("rigs")) for r in runs]
    live = [None if k else v for v, k in zip(all_live, sharded)]
    ceiling = [_num(r.get("transport_ceiling")) for r in runs]
    ceiling_rigs = [None if c is None else c / SAMPLE_RATE for c in ceiling]
    points(ax_l, live, "live rigs, one monitor (no loss, p99 < 50 ms; frames when the run had them)", "C3")
    if any(sharded):
        points(ax_l, [v if k else None for v, k in zip(all_live, sharded)], "live rigs, monitors sharded by --rigs",
               "C8", "D")
    points(ax_l, [_num((r.get("live_samples") or {}).get("rigs")) for r in runs], "live_samples rigs", "C6", "^")
    ax_l.axhline(LIVE_FRAMED_TARGET_RIGS, color="C3", ls=":", lw=1)
    points(ax_l, ceiling_rigs, "transport ceiling / 100 Hz", "C4", "s")
    points(ax_l, [None if c is None else c * CEILING_SHARE_TARGET for c in ceiling_rigs],
           "50 % of the ceiling", "C4", "_")
    ax_l.axhline(LIVE_TARGET_RIGS, color="C3", ls="--", lw=1)
    ax_l.set_ylabel("rigs at 100 Hz (dashed: 1000, dotted: 3000 with frames)")
    ax_l.set_title("live sim + monitor over loopback zenoh")
    ax_l.legend(fontsize=8, loc="upper left")

    share = [None if (lv is None or c is None or c <= 0) else lv / c for lv, c in zip(live, ceiling_rigs)]
    points(ax_s, share, "live / ceiling", "C3")
    ax_s.axhline(CEILING_SHARE_TARGET, color="C3", ls="--", lw=1)
    ax_s.set_ylim(0, max([CEILING_SHARE_TARGET * 1.4] + [s * 1.15 for s in share if s is not None]))
    ax_s.set_ylabel("share of the ceiling (dashed: 0.5)")

    kernel = [_num(r.get("kernel_us_per_sample")) for r in runs]
    points(ax_u, kernel, "kernel_us_per_sample", "C1")
    points(ax_u, [_num(r.get("monitor_us_per_sample")) for r in runs], "monitor_us_per_sample", "C3")
    points(ax_u, [None if k is None else k * MONITOR_KERNEL_RATIO_TARGET for k in kernel], "2 x kernel", "C1", "_")
    ax_u.set_ylabel("us per sample")
    ax_u.set_title("the monitor's CPU per sample (live, all threads) against the kernel's (one thread)")
    ax_u.legend(fontsize=8, loc="upper left")
    ax_u.set_xticks(x)
    ax_u.set_xticklabels([str(r.get("timestamp", "?"))[:16].replace("T", " ") for r in runs], rotation=60,
                         ha="right", fontsize=7)
    ax_u.set_xlabel("run (UTC); each run's figures come from one machine state: compare within a run")
    return fig
