"""Argument checks the commands share, run before any side effect (files, bus, banners, work),
and the all-or-nothing file write of the commands that write one result file.

Every check raises ValueError with a one-line message naming the option; ``hydromon.cli.main``
prints it as ``hydromon CMD: error: ...`` and exits with 2.
"""

from __future__ import annotations

import math
import os
import shutil
import signal
import tempfile
import threading
from contextlib import contextmanager, suppress
from pathlib import Path


def positive(option: str, value: float | None, *, unit: str = "s") -> None:
    """``value`` (None = not given) must be a finite number > 0."""
    if value is not None and not (math.isfinite(value) and value > 0):
        raise ValueError(f"{option} {value!r} must be a finite number > 0{' ' + unit if unit else ''}")


def non_negative(option: str, value: float | None, *, unit: str = "") -> None:
    """``value`` (None = not given) must be a finite number >= 0."""
    if value is not None and not (math.isfinite(value) and value >= 0):
        raise ValueError(f"{option} {value!r} must be a finite number >= 0{' ' + unit if unit else ''}")


def at_least(option: str, value: int | None, low: int) -> None:
    """An integer option (None = not given) must be >= ``low``."""
    if value is not None and value < low:
        raise ValueError(f"{option} {value!r} must be >= {low}")


def port(option: str, value: int | None) -> None:
    """A TCP port option (None = not given) must be 0..65535 (0: a free one)."""
    if value is not None and not 0 <= value <= 65535:
        raise ValueError(f"{option} {value!r} must be 0..65535")


def rigs_pattern(option: str, value: str) -> str:
    """A rig-id key-expression chunk (``hydromon.bus.monitor.rig_pattern``), as zenoh spells it."""
    from hydromon.bus.monitor import rig_pattern

    try:
        return rig_pattern(value)
    except ValueError as exc:
        raise ValueError(f"{option}: {exc}") from None


def fits_on_disk(option: str, path: str | os.PathLike, nbytes: float, what: str) -> None:
    """``nbytes`` (an estimate of what is to be written) fit in the free space of ``path``'s
    file system; a refusal says both figures. Writing beside the target and renaming needs the
    room once more only if an old file is being replaced, which is not counted."""
    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    try:
        free = shutil.disk_usage(parent if parent.exists() else ".").free
    except OSError:
        return  # cannot tell: the write itself will say
    if nbytes > free:
        raise ValueError(f"{option} {str(p)!r}: {what} is about {nbytes / 1e9:.3g} GB and the disk has "
                         f"{free / 1e9:.3g} GB free")


def writable_file(option: str, path: str | os.PathLike) -> None:
    """``path`` can be written as a file: not a directory, its directory exists and is writable."""
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"{option} {str(p)!r} is a directory; give a file name")
    if p.exists() and not p.is_file():  # a device or pipe, e.g. /dev/stdout: written in place
        if not os.access(p, os.W_OK):
            raise ValueError(f"{option} {str(p)!r} is not writable")
        return
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.exists():
        raise ValueError(f"{option} {str(p)!r}: directory {str(parent)!r} does not exist")
    if not parent.is_dir():
        raise ValueError(f"{option} {str(p)!r}: {str(parent)!r} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"{option} {str(p)!r}: directory {str(parent)!r} is not writable")
    if p.exists() and not os.access(p, os.W_OK):
        raise ValueError(f"{option} {str(p)!r} is not writable")


def not_an_input(option: str, path: str | os.PathLike, inputs) -> None:
    """``path`` (an output file) is none of ``inputs`` (paths this command reads; None ignored):
    writing it would destroy what the command was given, whatever ``--force`` says."""
    out = Path(path).resolve()
    for given in inputs:
        if given is not None and Path(given).resolve() == out:
            raise ValueError(f"{option} {str(path)!r} is one of this command's inputs; writing it would destroy "
                             "it: give another file")


def writable_dir(option: str, path: str | os.PathLike) -> None:
    """``path`` is a writable directory, or can be created as one (its nearest existing
    ancestor is a writable directory)."""
    p = Path(path)
    if p.exists():
        if not p.is_dir():
            raise ValueError(f"{option} {str(p)!r} exists and is not a directory")
        if not os.access(p, os.W_OK | os.X_OK):
            raise ValueError(f"{option} {str(p)!r}: directory is not writable")
        return
    ancestor = p.absolute().parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise ValueError(f"{option} {str(p)!r}: {str(ancestor)!r} is not a directory")
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise ValueError(f"{option} {str(p)!r}: cannot create it, {str(ancestor)!r} is not writable")


def _read_umask() -> int:
    mask = os.umask(0)  # the only way to read it; done once, at import, before any thread
    os.umask(mask)
    return mask


_UMASK = _read_umask()


_ACTIVE: list[str] = []  # temporary files being written


def _terminated(signum, frame):
    # remove them and exit at once: an exception raised here could land in code that swallows
    # it (a garbage-collection callback: measured, the run then finished with exit 0)
    for tmp in list(_ACTIVE):
        with suppress(OSError):
            os.unlink(tmp)
    os._exit(128 + signum)


@contextmanager
def _sigterm_removes():
    """SIGTERM removes the temporary files and exits, in the main thread, for the duration (by
    default it kills the process where it stands and leaves them behind)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextmanager
def replace_on_success(path: str | os.PathLike, mode: str = "w", **open_kw):
    """Open a temporary file beside ``path``; on a clean exit it replaces ``path`` atomically,
    on an exception (or SIGTERM) it is removed, so ``path`` is never left truncated or half
    written and an existing file is only replaced by a complete one. A symbolic link's target
    is replaced; a device or pipe (``/dev/stdout``) is written in place."""
    if Path(path).exists() and not Path(path).is_file():
        with open(path, mode, **open_kw) as f:
            yield f
        return
    p = Path(os.path.realpath(path))
    with _sigterm_removes():
        fd, tmp = tempfile.mkstemp(dir=p.parent if str(p.parent) else ".", prefix=f".{p.name}.", suffix=".part")
        _ACTIVE.append(tmp)
        try:
            with os.fdopen(fd, mode, **open_kw) as f:
                yield f
                f.flush()
                os.fsync(f.fileno())  # on disk before it replaces the old file
            if p.exists():
                os.chmod(tmp, p.stat().st_mode & 0o7777)  # keep the replaced file's permissions
            else:
                os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes 0600; a new file gets open()'s mode
            os.replace(tmp, p)
        except BaseException:
            with suppress(FileNotFoundError):
                os.unlink(tmp)
            raise
        finally:
            _ACTIVE.remove(tmp)
