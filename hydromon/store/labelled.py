"""Labelled-record lists for ``hydromon calibrate --labelled``: which recording of which rig had
which grade (e.g. from maintenance records), as CSV or TOML.

CSV: a header ``recording,grade`` and optionally ``rig`` (other columns, notes say, are
ignored); TOML: ``[[records]]`` tables with the same keys and no other. ``recording`` is a .mcap
or .csv path, relative to the list file's directory unless absolute; ``grade`` one of health,
sub-health, average, deterioration, fault (or 0-4); ``rig`` picks the rig of a multi-rig MCAP.
"""

from __future__ import annotations

import csv
import tomllib
from dataclasses import dataclass
from pathlib import Path

from hydromon.contract import GRADES

__all__ = ["LabelledRecord", "load_labelled"]

_KEYS = ("recording", "grade", "rig")


@dataclass(frozen=True)
class LabelledRecord:
    """One entry: the recording's path, its rig (None: the only one), its grade 0..4."""

    path: Path
    rig: str | None
    grade: int


def _grade(value, where: str) -> int:
    text = str(value).strip()
    if text in GRADES:
        return GRADES.index(text)
    if text in ("0", "1", "2", "3", "4"):
        return int(text)
    raise ValueError(f"{where}: grade {text!r} is not one of {', '.join(GRADES)} (or 0-4)")


def load_labelled(path: str | Path) -> list[LabelledRecord]:
    """The entries of a list file; ValueError naming the file, the line and the problem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such file") from None
    except (OSError, UnicodeError) as exc:
        raise ValueError(f"{path}: cannot be read ({exc})") from None
    if path.suffix.lower() == ".toml":
        try:
            rows = tomllib.loads(text).get("records")
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{path}: not TOML ({exc})") from None
        if not isinstance(rows, list):
            raise ValueError(f"{path}: a TOML list needs [[records]] tables with recording and grade")
        items = [(f"{path} record {i + 1}", r) for i, r in enumerate(rows)]
        for where, r in items:  # a misspelt key (``rigg``) would be dropped without a word
            unknown = sorted(set(r) - set(_KEYS)) if isinstance(r, dict) else []
            if unknown:
                raise ValueError(f"{where}: unknown key(s) {', '.join(map(repr, unknown))} (a record takes "
                                 f"{', '.join(_KEYS)})")
    else:
        reader = csv.DictReader(text.splitlines())
        if not reader.fieldnames or not {"recording", "grade"} <= {f.strip() for f in reader.fieldnames}:
            raise ValueError(f"{path} line 1: a CSV list needs a header with columns recording,grade (and rig)")
        items = [(f"{path} line {i + 2}", {k.strip(): v for k, v in r.items() if k}) for i, r in enumerate(reader)]
    out = []
    for where, r in items:
        if not isinstance(r, dict) or not r.get("recording") or r.get("grade") in (None, ""):
            raise ValueError(f"{where}: needs a recording and a grade")
        rec = Path(str(r["recording"]).strip())
        if not rec.is_absolute():
            rec = path.parent / rec
        rig = r.get("rig")
        out.append(LabelledRecord(rec, str(rig).strip() or None if rig is not None else None, _grade(r["grade"], where)))
    if not out:
        raise ValueError(f"{path}: no records listed")
    return out
