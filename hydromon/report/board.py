"""``hydromon watch``'s board as text: a plain table, or a ``rich`` table for a terminal.

The rigs come in the order :func:`hydromon.engine.board.attention_order` gives; the "why"
column says in words which parameters carry the rig's grade and how far they moved
(``hydromon.engine.words.why_words``), last, where a long text does not push the numbers apart.
"""

from __future__ import annotations

from hydromon.contract import GRADES
from hydromon.engine.board import Board, attention_order
from hydromon.report.cells import GRADE_STYLE, TABLE_PARAMS, fmt_value
from hydromon.engine.words import CONFIDENCE_HELP, known_ranges, why_words

__all__ = ["BOARD_HEAD", "AGE_UNKNOWN", "board_columns", "board_counts", "board_events", "board_rows",
           "render_board_plain",
           "render_board_rich"]


BOARD_HEAD = ["rig", "grade", "conf", "status", *TABLE_PARAMS, "t [s]", "age [s]", "why"]

AGE_UNKNOWN = ("age -: no verdict of the rig was published while watch listened; it shows the monitor's last one, "
               "of unknown age (a stale rig has been silent at least the monitor's --stale-after, 2 s by default)")
"""The line under a board with an age it cannot know."""


def _why(h: dict) -> str:
    """Why the rig has its grade, in words (none for health or unknown)."""
    if h["level"] is None or h["level"] == 0:
        return "-"
    return "; ".join(why_words(h, known_ranges(h), units=True)) or "-"


def board_rows(board: Board, now: float, top: int | None = None,
               since: dict | None = None) -> tuple[list[list[str]], int]:
    """Rows of :data:`BOARD_HEAD` (strings), the rigs that need attention first, and how many
    rigs ``top`` left out. The age is ``now`` less ``since[rig]``, when the rig's verdict was
    published (None: unknown, ``-``), or less its arrival on the board without ``since``."""
    items = sorted(board.latest.items(), key=lambda it: attention_order(it, board.status(it[0])))
    shown = items if top is None else items[:top]
    rows = []
    for rig, h in shown:
        at = board.arrived[rig] if since is None else since.get(rig)
        rows.append([rig, h["grade"], f"{h['confidence']:.2f}", board.status(rig),
                     *[fmt_value(h["params"].get(p)) for p in TABLE_PARAMS], f"{h['t']:.1f}",
                     "-" if at is None else f"{max(0.0, now - at):.1f}", _why(h)])
    return rows, len(items) - len(shown)


def board_events(board: Board, now: float) -> list[str]:
    """The latest events, newest first, one line each: how long ago, rig, from -> to, reason."""
    return [f"{max(0.0, now - at):6.1f} s ago  {rig}  {ev['kind']} {ev['from']} -> {ev['to']}"
            + (f": {ev['reason']}" if ev.get("reason") else "")
            for rig, ev, at in reversed(board.events)]


def board_counts(board: Board) -> str:
    """One line: rigs per grade, worst first, and the invalid payloads if any."""
    n = board.grade_counts()
    bad = sum(1 for h in board.latest.values() if h["status"] == "bad-input")
    parts = [f"{n[g]} {g}" for g in (*reversed(GRADES), "unknown") if n[g]]
    line = f"{len(board.latest)} rig(s)" + (f": {', '.join(parts)}" if parts else "")
    if bad:
        line += f"; {bad} with bad input"
    if board.invalid:
        line += f"; {board.invalid} invalid payload(s) ignored"
    return line


def render_board_plain(board: Board, now: float, top: int | None = None, since: dict | None = None) -> str:
    """The board as aligned plain text: the counts line, the table, and what its conf and an
    unknown age mean."""
    rows, more = board_rows(board, now, top, since)
    table = [BOARD_HEAD, *rows]
    widths = [max(len(r[i]) for r in table) for i in range(len(BOARD_HEAD))]
    lines = [board_counts(board)]
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in table]
    if more:
        lines.append(f"... and {more} more rig(s) (--top N shows more)")
    if rows:
        lines.append(CONFIDENCE_HELP)
    if any(r[BOARD_HEAD.index("age [s]")] == "-" for r in rows):
        lines.append(AGE_UNKNOWN)
    events = board_events(board, now)
    if events:
        lines += ["latest events:", *(f"  {e}" for e in events)]
    return "\n".join(lines)


# columns a narrow terminal loses first (rich would otherwise cut every number to "0.0…")
_DROP_ORDER = ("t [s]", "C_ip", "B_fv", "f_c", "conf")


def board_columns(rows: list[list[str]], width: int | None) -> list[int]:
    """Indices of the :data:`BOARD_HEAD` columns that fit ``width`` characters (None: all), each
    at its widest cell with rich's padding: the least needed ones go first (``_DROP_ORDER``)."""
    need = [max([len(name), *(len(r[i]) for r in rows)]) for i, name in enumerate(BOARD_HEAD)]
    need[-1] = min(need[-1], 24)  # why: rich wraps it
    keep = list(range(len(BOARD_HEAD)))
    for name in (None, *_DROP_ORDER):
        if name is not None:
            keep.remove(BOARD_HEAD.index(name))
        if width is None or sum(need[i] + 2 for i in keep) + 2 <= width:  # padding and separators
            break
    return keep


def render_board_rich(board: Board, now: float, top: int | None = None, title: str = "",
                      width: int | None = None, since: dict | None = None):
    """The board as a ``rich.table.Table`` (grades coloured) for a terminal ``width`` wide
    (:func:`board_columns`)."""
    from rich import box
    from rich.markup import escape
    from rich.table import Table

    rows, more = board_rows(board, now, top, since)
    keep = board_columns(rows, width)
    notes = [f"... and {more} more rig(s) (--top N shows more)"] if more else []
    notes += [CONFIDENCE_HELP] if rows else []
    notes += [AGE_UNKNOWN] if any(r[BOARD_HEAD.index("age [s]")] == "-" for r in rows) else []
    events = board_events(board, now)
    notes += ["latest events:", *(f"  {e}" for e in events)] if events else []
    caption = escape("\n".join(notes)) if notes else None
    table = Table(title=f"{title}\n{board_counts(board)}" if title else board_counts(board), title_justify="left",
                  caption=caption, caption_justify="left", box=box.SIMPLE_HEAD, pad_edge=False,
                  padding=(0, 1, 0, 0))
    for i in keep:
        name = BOARD_HEAD[i]
        table.add_column(escape(name), justify="right" if name in (*TABLE_PARAMS, "conf", "t [s]", "age [s]")
                         else "left", no_wrap=name != "why")  # escaped: "[s]" is rich's strike-through markup
    for row in rows:
        style = GRADE_STYLE.get(row[1], "")
        row[1] = f"[{style}]{row[1]}[/]" if style else row[1]
        if row[3] == "bad-input":
            row[3] = "[red]bad-input[/]"
        table.add_row(*(escape(row[i]) if BOARD_HEAD[i] == "why" else row[i] for i in keep))
    return table
