"""Point numba's on-disk cache at a directory keyed by a hash of the numerical core's sources.

Called explicitly by the entry points (the ``hydromon`` command, the test suite, the scripts
under ``benchmarks/``) before any kernel is compiled; importing the core configures nothing.

numba keys a cached function on its own file only: a kernel that calls a changed kernel in
another module (monitor.pipeline calling monitor.grading, for one) would otherwise load stale
machine code after an upgrade. Keying the whole directory on every core source file makes any
change recompile everything once. An explicit NUMBA_CACHE_DIR from the user wins.
Directories of other versions untouched for STALE_DAYS are removed (each is a few MB, and a
developer leaves one behind per change).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

_ROOT = Path(__file__).resolve().parents[2]
_PACKAGES = ("plant_sim", "monitor")
STALE_DAYS = 7.0


def _source_hash() -> str:
    h = hashlib.sha256()
    for pkg in _PACKAGES:
        for path in sorted((_ROOT / pkg).rglob("*.py")):
            h.update(path.relative_to(_ROOT).as_posix().encode())
            h.update(path.read_bytes())
    return h.hexdigest()[:16]


def prune(base: Path, keep: Path, now: float, stale_days: float = STALE_DAYS) -> list[Path]:
    """Remove the cache directories under ``base`` other than ``keep`` whose newest file is
    older than ``stale_days``; returns them. Never raises (a cache is not worth an error)."""
    import shutil

    removed = []
    try:
        dirs = [d for d in base.iterdir() if d.is_dir() and d != keep]
    except OSError:
        return removed
    for d in dirs:
        try:
            newest = max([d.stat().st_mtime] + [f.stat().st_mtime for f in d.iterdir()])
        except OSError:
            continue
        if now - newest > stale_days * 86400.0:
            shutil.rmtree(d, ignore_errors=True)
            removed.append(d)
    return removed


def numba_subdir(source_dir: Path) -> str:
    """The directory under NUMBA_CACHE_DIR where numba keeps the kernels of the modules in
    ``source_dir``: its name and the SHA-1 of its absolute path
    (``numba.core.caching._CacheLocator.get_suitable_cache_subpath``). Two checkouts of the same
    version share the cache directory (it is keyed on the sources' content) but not these."""
    path = os.path.abspath(source_dir)
    return f"{os.path.basename(path)}_{hashlib.sha1(path.encode()).hexdigest()}"


def is_cold(root: Path = _ROOT, dirs: tuple | None = None) -> bool:
    """True when numba's cache holds no compiled kernel yet for one of the source directories
    ``dirs`` (relative to the checkout ``root``; None: the packages' top directories): the
    first run of this version from here, which compiles every kernel it calls (about a minute).
    numba keeps a module's kernels under its own directory's name, so a command names the
    directories whose kernels it runs (``hydromon audit``: monitor's outlier gate, monitor/audit
    and plant_sim). Kernels another checkout of the same sources compiled do not count:
    numba keys them on their files' paths, so this one compiles its own."""
    cache = os.environ.get("NUMBA_CACHE_DIR")
    if not cache:
        return False  # numba caches beside the sources: we cannot tell cheaply
    try:
        return not all(any((Path(cache) / numba_subdir(root / d)).glob("*.nbi")) for d in dirs or _PACKAGES)
    except OSError:
        return False


def configure() -> None:
    """Set NUMBA_CACHE_DIR to ``$XDG_CACHE_HOME/hydromon/numba/<hash of the core's sources>``
    (``~/.cache`` without XDG_CACHE_HOME) unless the user set it; prune stale versions."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "hydromon" / "numba"
    path = base / _source_hash()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return  # read-only home: numba falls back to __pycache__
    import time

    prune(base, path, time.time())
    os.environ["NUMBA_CACHE_DIR"] = str(path)
    import sys

    if "numba" in sys.modules:  # imported already: its config read the environment
        sys.modules["numba"].config.CACHE_DIR = str(path)
