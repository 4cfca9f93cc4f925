"""The monitor node's checkpoints: restored at its start, written off its loop while it runs.

The state itself is ``hydromon.engine.checkpoint``'s; the file ``hydromon.store.state_dir``'s.
"""

from __future__ import annotations

import logging
import threading
import time

from hydromon.engine.checkpoint import CheckpointRefused, decode, encode, restore, snapshot
from hydromon.engine.core import MonitorCore
from hydromon.store.state_dir import StateDir

__all__ = ["Saver", "restore_from"]

log = logging.getLogger("hydromon.bus.monitor")  # the node's log: these lines are its


def restore_from(core: MonitorCore, state_dir: StateDir) -> None:
    """The node's checkpoint into ``core``, or a log line saying why not."""
    data = state_dir.load()
    if data is None:
        log.warning("monitor: no checkpoint in %s yet: every rig starts afresh", state_dir.path)
        return
    age = state_dir.age(time.time_ns())
    try:
        refused = restore(core, decode(data))
    except CheckpointRefused as exc:
        log.error("monitor: checkpoint %s refused, every rig starts afresh: %s", state_dir.file, exc)
        return
    for rig_id, why in refused:
        log.error("monitor: rig %s not restored (it starts afresh): %s", rig_id, why)
    log.warning("monitor: %d rig(s) restored from %s (written %.1f s ago); each resumes after a gap",
                len(core.rigs), state_dir.file, age or 0.0)


class Saver:
    """Checkpoints written off the node's loop: the state is copied between two batches
    (``snapshot``), encoded and written in a thread; one write at a time (a save asked for while
    one runs is skipped: the next one comes ``checkpoint_s`` later)."""

    def __init__(self, state_dir: StateDir):
        self.state_dir = state_dir
        self._thread: threading.Thread | None = None
        self._failed = False

    def save(self, core: MonitorCore) -> None:
        if self._thread is not None and self._thread.is_alive():
            return
        ckpt = snapshot(core)
        self._thread = threading.Thread(target=self._write, args=(ckpt,), name="checkpoint", daemon=True)
        self._thread.start()

    def _write(self, ckpt) -> None:
        try:
            self.state_dir.save(encode(ckpt))
        except OSError as exc:
            if not self._failed:
                log.error("monitor: checkpoint not written to %s (the previous one is kept): %s",
                          self.state_dir.file, exc)
            self._failed = True
            return
        if self._failed:
            log.warning("monitor: checkpoints written to %s again", self.state_dir.file)
        self._failed = False

    def close(self, core: MonitorCore | None) -> None:
        """Wait for the write under way; then the final checkpoint of ``core`` (None: none)."""
        if self._thread is not None:
            self._thread.join()
        if core is not None:
            self._write(snapshot(core))
