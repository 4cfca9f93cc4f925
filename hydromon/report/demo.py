"""``hydromon demo``'s tables: the live table of every rig's latest health, and the closing summary."""

from __future__ import annotations

from contextlib import contextmanager
from typing import TYPE_CHECKING

from hydromon.report.cells import GRADE_STYLE, TABLE_PARAMS, fmt_value
from hydromon.engine.words import CONFIDENCE_HELP, known_ranges, why_words

if TYPE_CHECKING:
    from hydromon.bus.demo import DemoResult

__all__ = ["render_plain", "render_rich", "live_display", "summary"]


def _rows(ids, health: dict, truth: dict):
    for rig in ids:
        h = health.get(rig)
        if h is None:
            yield [rig, "-", "-", "waiting", *["-"] * len(TABLE_PARAMS), "-", truth.get(rig) or "?"]
            continue
        yield [rig, h["grade"], f"{h['confidence']:.2f}", h["status"],
               *[fmt_value(h["params"].get(p)) for p in TABLE_PARAMS], f"{h['t']:.1f}", truth.get(rig) or "?"]


_HEAD = ["rig", "grade", "conf", "status", *TABLE_PARAMS, "t [s]", "true"]


def render_plain(ids, health: dict, truth: dict) -> str:
    """The table of the latest health as aligned plain text."""
    rows = [_HEAD, *_rows(ids, health, truth)]
    widths = [max(len(r[i]) for r in rows) for i in range(len(_HEAD))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows)


def render_rich(ids, health: dict, truth: dict, title: str = ""):
    """The table of the latest health as a ``rich.table.Table``."""
    from rich import box
    from rich.table import Table

    t = max((h["t"] for h in health.values()), default=0.0)
    table = Table(title=f"{title}\nrig time {t:.1f} s" if title else None, title_justify="left",
                  box=box.SIMPLE_HEAD, pad_edge=False, padding=(0, 1, 0, 0))
    for name in _HEAD[:-2]:  # rig time is in the title, the true grade in the closing summary
        table.add_column(name, justify="right" if name in (*TABLE_PARAMS, "conf") else "left",
                         no_wrap=name in ("rig", "grade", "status"))
    for row in _rows(ids, health, truth):
        style = GRADE_STYLE.get(row[1], "")
        row[1] = f"[{style}]{row[1]}[/]" if style else row[1]
        table.add_row(*row[:-2])
    return table


def summary(result: DemoResult, ids) -> str:
    """The closing report: where the recording is, final grade next to the true grade and why,
    what conf means, and what to do next with the recording."""
    lines = []
    for path in result.recordings:
        lines.append(f"recording: {path} ({result.recorded} messages)")
    head = ["rig", "final grade", "true grade", "right", "status", "conf", "why"]
    rows = [head]
    for rig in ids:
        h = result.health.get(rig, {})
        truth = result.truth.get(rig)
        mark = "?" if truth is None or not h else ("yes" if h.get("grade") == truth else "NO")
        rows.append([rig, h.get("grade", "-"), truth or "?", mark, h.get("status", "-"),
                     f"{h['confidence']:.2f}" if h else "-", "; ".join(why_words(h, known_ranges(h), units=True))
                     or "-" if h else "-"])
    widths = [max(len(r[i]) for r in rows) for i in range(len(head))]
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() or "-" for r in rows]
    known = sum(1 for g in result.truth.values() if g is not None)
    lines.append(f"{result.matches}/{known} rigs at their true grade after {result.samples} samples per rig")
    lines.append(CONFIDENCE_HELP)
    if result.recordings:
        rec = result.recordings[0]
        lines += ["next:",
                  f"  hydromon evaluate {rec}      # every rig graded again from the recording, worst first",
                  f"  hydromon replay {rec} --direct > verdicts.jsonl   # the monitor's verdicts again",
                  f"  hydromon dashboard --recording {rec}   # in a web browser: each rig's history and events",
                  "  (an MCAP viewer such as Foxglove opens it too: JSON messages with their schemas)"]
    return "\n".join(lines)


@contextmanager
def live_display(stream, first):
    """A ``rich.live.Live`` display on ``stream`` showing ``first``; yields ``update(renderable)``."""
    from rich.console import Console
    from rich.live import Live

    with Live(first, console=Console(file=stream), refresh_per_second=4, transient=False) as lv:
        yield lv.update
