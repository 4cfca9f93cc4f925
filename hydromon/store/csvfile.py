"""CSV records of one rig: header ``t,ug,x1,x3,x4,x5`` (any order, extra columns ignored), SI units.

:func:`read_csv` validates as it reads (every error names the file and line); :func:`csv_text`
writes what it reads back exactly.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from hydromon.contract import DRIVE, DRIVE_LIMIT, SAMPLE_COLUMNS, SAMPLE_LIMITS

__all__ = ["read_csv", "csv_text"]


def read_csv(src, name: str = "<csv>", drive: list | None = None) -> np.ndarray:
    """Parse a CSV with header columns t,ug,x1,x3,x4,x5 (any order, extra columns ignored).

    src is a path or a text stream. Returns (N, 6) float64 in SAMPLE_COLUMNS order. Raises
    ValueError naming the line of the first bad value (header = line 1); a missing file raises
    FileNotFoundError naming it. A UTF-8 byte order mark before the header is allowed.
    With a ``drive`` list, the optional column ``u`` (the valve drive [V]) is read into it, one
    value per row (NaN for an empty cell or without the column).
    """
    if isinstance(src, (str, Path)):
        text = _read_text(Path(src))
        try:
            return read_csv(io.StringIO(text, newline=""), str(src), drive)
        except ValueError as exc:
            last = text.count("\n") + 1  # the line number of an unterminated last line
            if text and not text.endswith(("\n", "\r")) and f" line {last}:" in str(exc):
                raise ValueError(f"{exc}; it is the last line and has no line end: was the file cut short "
                                 "(a logger stopped mid-write)? Remove that line") from None
            raise
    reader = csv.reader(src)
    try:
        first = next(reader)
    except StopIteration:
        raise ValueError(f"{name}: empty file; expected a header {','.join(SAMPLE_COLUMNS)}") from None
    if first:  # Excel's "CSV UTF-8" starts with a byte order mark
        first[0] = first[0].removeprefix("\ufeff")
    header = [h.strip() for h in first]
    missing = [c for c in SAMPLE_COLUMNS if c not in header]
    if missing:
        raise ValueError(f"{name} line 1: header {','.join(header)!r} lacks column(s) "
                         f"{', '.join(missing)}; expected {','.join(SAMPLE_COLUMNS)} (SI units)")
    dup = sorted({c for c in (*SAMPLE_COLUMNS, DRIVE) if header.count(c) > 1})
    if dup:
        raise ValueError(f"{name} line 1: column(s) {', '.join(dup)} appear more than once")
    cols = [header.index(c) for c in SAMPLE_COLUMNS]
    u_col = header.index(DRIVE) if drive is not None and DRIVE in header else None
    rows = []
    blank = None  # the first blank line seen: an error only if a row follows it
    for row in reader:
        line = reader.line_num
        if not row or all(not c.strip() for c in row):
            blank = blank or line
            continue
        if blank is not None:
            raise ValueError(f"{name} line {blank}: empty line")
        if len(row) != len(header):
            raise ValueError(f"{name} line {line}: {len(row)} fields, the header has {len(header)}")
        vals = [_number(name, line, c, row[j]) for c, j in zip(SAMPLE_COLUMNS, cols)]
        rows.append(vals)
        if drive is not None:
            drive.append(math.nan if u_col is None or not row[u_col].strip() else _number(name, line, DRIVE, row[u_col]))
    if not rows:
        raise ValueError(f"{name}: no samples after the header")
    return np.array(rows, dtype=np.float64)


def _number(name: str, line: int, column: str, text: str) -> float:
    """The value of one cell: a finite number within the contract's limit for its column."""
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"{name} line {line}: {column} = {text!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{name} line {line}: {column} = {text!r} is not finite")
    limit = DRIVE_LIMIT if column == DRIVE else SAMPLE_LIMITS.get(column, math.inf)
    if abs(v) > limit:
        raise ValueError(f"{name} line {line}: {column} = {text!r} is beyond the contract's limit "
                         f"|{column}| <= {limit:g} (SI units?)")
    return v


def _read_text(path: Path) -> str:
    """A CSV file's text; every error names the file (and the line of a byte that is not UTF-8)."""
    name = str(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise FileNotFoundError(f"{name}: no such file") from None
    except OSError as exc:
        raise ValueError(f"{name}: cannot be read ({exc.strerror or exc})") from None
    try:
        return data.decode("utf-8")  # not utf-8-sig: its error offsets leave out the mark; read_csv drops it
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise ValueError(f"{name} line {line}: byte {data[exc.start]:#04x} is not UTF-8 text; expected a CSV "
                         f"with the header {','.join(SAMPLE_COLUMNS)} (is it a binary file?)") from None


def csv_text(t: np.ndarray, samples: np.ndarray, u: np.ndarray | None = None) -> str:
    """CSV text that :func:`read_csv` reads back exactly: header SAMPLE_COLUMNS, t [s] (N,) and
    samples (N, 5) [SI] at full precision; with ``u`` (N,), the valve drive [V] as column ``u``."""
    out = io.StringIO()
    out.write(",".join((*SAMPLE_COLUMNS, DRIVE) if u is not None else SAMPLE_COLUMNS) + "\n")
    rows = zip(t, samples) if u is None else zip(t, samples, u)
    for ti, row, *drive in rows:
        out.write(",".join(repr(float(v)) for v in (ti, *row, *drive)) + "\n")
    return out.getvalue()
