"""A monitor's state directory: its checkpoint file, written so that a crash never leaves half
of one.

:meth:`StateDir.save` writes the new checkpoint beside the old one, flushes it to the disk
(``fsync``), renames it over the old one (atomic on POSIX) and flushes the directory, so the
file is at every instant either the previous checkpoint or the new one, whole. The monitors of
one failover group (a primary and its standbys) share one directory; shards of a plant use one
each.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["CHECKPOINT_NAME", "StateDir"]

CHECKPOINT_NAME = "monitor.ckpt.npz"


class StateDir:
    """The directory ``path`` (created if missing) and its checkpoint file.

    Raises ``ValueError`` when ``path`` exists and is not a writable directory.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ValueError(f"state directory {self.path}: {exc.strerror or exc}") from None
        if not self.path.is_dir() or not os.access(self.path, os.W_OK | os.X_OK):
            raise ValueError(f"state directory {self.path}: not a writable directory")
        self.file = self.path / CHECKPOINT_NAME

    def load(self) -> bytes | None:
        """The checkpoint's bytes; None when there is none yet."""
        try:
            return self.file.read_bytes()
        except FileNotFoundError:
            return None

    def age(self, now_ns: int) -> float | None:
        """Seconds since the checkpoint was written (wall clock ``now_ns`` [ns]); None if none."""
        try:
            return (now_ns - self.file.stat().st_mtime_ns) / 1e9
        except FileNotFoundError:
            return None

    def save(self, data: bytes) -> None:
        """Replace the checkpoint with ``data``, atomically and durably (``OSError`` on failure,
        the previous checkpoint left as it was)."""
        tmp = self.file.with_name(f".{self.file.name}.{os.getpid()}.tmp")
        try:
            with open(tmp, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.file)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        fd = os.open(self.path, os.O_RDONLY)
        try:
            os.fsync(fd)  # the rename itself reaches the disk
        finally:
            os.close(fd)
