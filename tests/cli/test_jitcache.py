"""numba's cache directory: keyed by the core's sources, stale versions pruned."""

from __future__ import annotations

import os
import time

from hydromon.tools.jitcache import STALE_DAYS, prune


def test_stale_cache_directories_of_other_versions_are_removed(tmp_path):
    now = time.time()
    old = now - (STALE_DAYS + 1) * 86400
    current, stale, recent, stale_but_used = (tmp_path / n for n in ("cur", "stale", "recent", "used"))
    for d in (current, stale, recent, stale_but_used):
        d.mkdir()
        (d / "k.nbi").write_bytes(b"x")
    for d in (current, stale, stale_but_used):
        os.utime(d / "k.nbi", (old, old))
        os.utime(d, (old, old))
    os.utime(stale_but_used, (old, old))  # the directory is old, but one of its files is fresh
    (stale_but_used / "new.nbc").write_bytes(b"y")
    removed = prune(tmp_path, current, now)
    assert removed == [stale]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cur", "recent", "used"]
    assert prune(tmp_path / "missing", current, now) == []
