"""``hydromon watch``'s board as text: a plain table, or a ``rich`` table for a terminal.

The rigs come in the order :func:`hydromon.engine.board.attention_order` gives; the "why"
column names the parameters whose grade is the rig's grade: the ones that carry it.
"""

from __future__ import annotations

from hydromon.contract import GRADES
from hydromon.engine.board import Board, attention_order
from hydromon.report.cells import GRADE_STYLE, TABLE_PARAMS, fmt_value

__all__ = ["BOARD_HEAD", "board_columns", "board_counts", "board_events", "board_rows", "render_board_plain",
           "render_board_rich"]


BOARD_HEAD = ["rig", "grade", "conf", "status", "why", *TABLE_PARAMS, "t [s]", "age [s]"]


def _why(h: dict) -> str:
    """The graded parameters whose grade is the rig's (none for health or unknown)."""
    if h["level"] is None or h["level"] == 0:
        return "-"
    names = [p for p, g in h["param_grades"].items() if g == h["grade"]]
    return ",".join(names) or "-"


def board_rows(board: Board, now: float, top: int | None = None) -> tuple[list[list[str]], int]:
    """Rows of :data:`BOARD_HEAD` (strings), the rigs that need attention first, and how many
    rigs ``top`` left out."""
    items = sorted(board.latest.items(), key=lambda it: attention_order(it, board.status(it[0])))
    shown = items if top is None else items[:top]
    rows = []
    for rig, h in shown:
        rows.append([rig, h["grade"], f"{h['confidence']:.2f}", board.status(rig), _why(h),
                     *[fmt_value(h["params"].get(p)) for p in TABLE_PARAMS], f"{h['t']:.1f}",
                     f"{max(0.0, now - board.arrived[rig]):.1f}"])
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


def render_board_plain(board: Board, now: float, top: int | None = None) -> str:
    """The board as aligned plain text: the counts line, then the table."""
    rows, more = board_rows(board, now, top)
    table = [BOARD_HEAD, *rows]
    widths = [max(len(r[i]) for r in table) for i in range(len(BOARD_HEAD))]
    lines = [board_counts(board)]
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in table]
    if more:
        lines.append(f"... and {more} more rig(s) (--top N shows more)")
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
    keep = list(range(len(BOARD_HEAD)))
    for name in (None, *_DROP_ORDER):
        if name is not None:
            keep.remove(BOARD_HEAD.index(name))
        if width is None or sum(need[i] + 2 for i in keep) + 2 <= width:  # padding and separators
            break
    return keep


def render_board_rich(board: Board, now: float, top: int | None = None, title: str = "",
                      width: int | None = None):
    """The board as a ``rich.table.Table`` (grades coloured) for a terminal ``width`` wide
    (:func:`board_columns`)."""
    from rich import box
    from rich.markup import escape
    from rich.table import Table

    rows, more = board_rows(board, now, top)
    keep = board_columns(rows, width)
    events = board_events(board, now)
    caption = "\n".join(([f"... and {more} more rig(s) (--top N shows more)"] if more else [])
                        + (["latest events:", *(f"  {escape(e)}" for e in events)] if events else [])) or None
    table = Table(title=f"{title}\n{board_counts(board)}" if title else board_counts(board), title_justify="left",
                  caption=caption, caption_justify="left", box=box.SIMPLE_HEAD, pad_edge=False,
                  padding=(0, 1, 0, 0))
    for i in keep:
        name = BOARD_HEAD[i]
        table.add_column(escape(name), justify="right" if name in (*TABLE_PARAMS, "conf", "t [s]", "age [s]")
                         else "left", no_wrap=True)  # escaped: "[s]" is rich's strike-through markup
    for row in rows:
        style = GRADE_STYLE.get(row[1], "")
        row[1] = f"[{style}]{row[1]}[/]" if style else row[1]
        if row[3] == "bad-input":
            row[3] = "[red]bad-input[/]"
        table.add_row(*(row[i] for i in keep))
    return table
