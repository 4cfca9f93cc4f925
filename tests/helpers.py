"""Shared test helpers: polling for a condition, and where a rig's health messages fall."""

from __future__ import annotations

import time

from monitor.pipeline import eval_phase


def wait_for(pred, timeout_s: float, what: str, alive=None, poll_s: float = 0.02) -> None:
    """Poll ``pred()`` until true; AssertionError after ``timeout_s`` [s], or as soon as
    ``alive()`` (optional: e.g. a check that the node processes still run) raises."""
    deadline = time.monotonic() + timeout_s
    while not pred():
        if alive is not None:
            alive()
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(poll_s)


def health_seqs(rig_id: str, n: int, eval_every: int = 10, first: int = 0) -> list[int]:
    """Seqs of the samples after which the monitor (staggered, ``monitor.pipeline.eval_phase``)
    reports rig ``rig_id`` when it takes samples first .. n-1 with no restart."""
    ph = eval_phase(rig_id, eval_every)
    return [s for s in range(first, n) if (s - first + 1 + ph) % eval_every == 0]


def window_end(rig_id: str, s: int, eval_every: int = 10) -> int:
    """Seq of the health message whose window holds sample s (no restart)."""
    ph = eval_phase(rig_id, eval_every)
    e = s
    while (e + 1 + ph) % eval_every:
        e += 1
    return e
