"""The nodes in threads of one process, on one session: what ``hydromon demo`` and the golden
recordings (``hydromon.tools.goldens``) both do before their simulator publishes.

:class:`Worker` runs a node and keeps its result or exception; :func:`await_recorder_and_monitor`
returns once the recorder hears ``<ns>/**`` and the monitor's liveliness token is up (declared
after its subscriptions), so the simulator's first samples are heard by both.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from hydromon.contract import liveliness_key

__all__ = ["Worker", "wait_until", "await_recorder_and_monitor"]


class Worker(threading.Thread):
    """A daemon thread that keeps its target's result or exception (re-raised by the caller)."""

    def __init__(self, name: str, target: Callable):
        super().__init__(name=name, daemon=True)
        self._target_fn, self.result, self.error = target, None, None

    def run(self):
        try:
            self.result = self._target_fn()
        except BaseException as exc:  # re-raised in the caller
            self.error = exc


def wait_until(pred: Callable[[], bool], timeout_s: float, what: str, who: str,
               stop: threading.Event | None = None) -> None:
    """Poll ``pred`` every 10 ms until it holds; RuntimeError after ``timeout_s`` [s] naming
    ``who`` waited for ``what``. Returns early once ``stop`` is set."""
    stop = stop if stop is not None else threading.Event()
    deadline = time.monotonic() + timeout_s
    while not pred():
        if time.monotonic() > deadline:
            raise RuntimeError(f"{who}: timed out after {timeout_s} s waiting for {what}")
        if stop.wait(0.01):
            return


def await_recorder_and_monitor(session, namespace: str, node: str, rec: Worker, mon: Worker, who: str,
                               stop: threading.Event | None = None, timeout_s: float = 30.0) -> None:
    """Wait until the recorder ``rec`` and the monitor ``mon`` (node name ``node``) are listening
    on ``session``; re-raises a worker's error. ``who`` names the caller in a timeout."""
    # a probe only the recorder's <ns>/** matches, and the monitor's token (declared after its
    # subscriptions): once both are seen, the sim's first samples are heard
    probe = session.declare_publisher(f"{namespace}/{who}-probe")
    wait_until(lambda: probe.matching_status.matching or rec.error is not None, timeout_s, "the recorder", who, stop)
    probe.undeclare()
    token = liveliness_key(node, namespace)
    wait_until(lambda: mon.error is not None or any(
        r.ok is not None for r in session.liveliness().get(token, timeout=1.0)), timeout_s, "the monitor", who, stop)
    for w in (rec, mon):
        if w.error is not None:
            raise w.error
