"""A directory of per-rig health ranges, ``<rig-id>.json`` each, watched for changes.

:meth:`RangesDir.scan` compares each file's size and modification time with the last scan's and
returns what changed: a new or changed file read and validated (or the reason it was refused),
a removed file. Files whose name is not a rig id (``[A-Za-z0-9_-]{1,64}.json``) are ignored, as
are temporary files a writer renames into place (``.name.json.part``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from hydromon.contract import valid_rig_id
from monitor.ranges import Ranges

__all__ = ["RangesChange", "RangesDir", "ranges_tag"]


@dataclass(frozen=True)
class RangesChange:
    """A rig's ranges file appeared or changed (``ranges`` set, or ``error`` why it was refused),
    or was removed (neither)."""

    rig_id: str
    path: Path
    ranges: Ranges | None = None
    tag: str | None = None
    error: str | None = None

    @property
    def removed(self) -> bool:
        return self.ranges is None and self.error is None


def ranges_tag(path: Path, ranges: Ranges) -> str:
    """What a health graded on these ranges says: the file's name, and when they were made."""
    return f"{path.name} ({ranges.created})" if ranges.created else path.name


class RangesDir:
    """The ranges files of ``path`` (must be a directory)."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        if not self.path.is_dir():
            raise ValueError(f"--ranges-dir {str(self.path)!r} is not a directory")
        self._seen: dict[str, tuple[int, int]] = {}

    def scan(self) -> list[RangesChange]:
        """What changed since the last scan (every file, the first time), by rig id."""
        now: dict[str, tuple[int, int]] = {}
        try:
            entries = list(os.scandir(self.path))
        except OSError as exc:
            return [RangesChange("", self.path, error=f"cannot list {self.path}: {exc.strerror or exc}")]
        for e in entries:
            stem, ext = os.path.splitext(e.name)
            if ext != ".json" or not valid_rig_id(stem):
                continue
            try:
                st = e.stat()
            except OSError:
                continue
            now[stem] = (st.st_mtime_ns, st.st_size)
        out = []
        for rig_id, stamp in sorted(now.items()):
            if self._seen.get(rig_id) == stamp:
                continue
            path = self.path / f"{rig_id}.json"
            try:
                ranges = Ranges.load(path)
            except ValueError as exc:
                out.append(RangesChange(rig_id, path, error=str(exc)))
                continue
            if ranges.rig is None:
                out.append(RangesChange(rig_id, path, error=f"ranges file {str(path)!r} names no rig constants it "
                                                            "was made for (rig): commission the rig"))
                continue
            out.append(RangesChange(rig_id, path, ranges, ranges_tag(path, ranges)))
        for rig_id in sorted(set(self._seen) - set(now)):
            out.append(RangesChange(rig_id, self.path / f"{rig_id}.json"))
        self._seen = now
        return out
