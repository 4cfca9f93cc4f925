"""Commissioning live (``hydromon monitor --commission-new-rigs S``): a rig the monitor has no
ranges for is commissioned from its first S seconds, and its ranges file written into the
monitor's ranges directory.

This takes the rig as it is when first seen for new: a rig already worn would be graded
relative to its worn state from then on. So it is off by default, and says so loudly: a log
line when a rig's commissioning starts and ends, and status ``commissioning`` in its health
meanwhile. The numerics are ``monitor.commission``'s, run in a worker thread (the twin's runs
take seconds) on the samples the core kept for the rig (``MonitorCore.tap``); the file is written
atomically (a temporary file renamed into place), then the ranges directory's scan grades the rig
on it like any other file.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from hydromon.engine.core import MonitorCore
from hydromon.store.ranges_dir import RangesDir

__all__ = ["LiveCommissioning"]

log = logging.getLogger("hydromon.bus.monitor")  # the node's log: these lines are its


class LiveCommissioning:
    """Commission the rigs without ranges that ``core`` meets, from their first ``seconds`` [s].

    Parameters
    ----------
    ranges_dir : RangesDir
        Where the ranges files go (``<rig-id>.json``); a rig with a file there is never
        commissioned.
    seconds : float
        Seconds of a rig's samples to commission it from (at least ``monitor.commission.MIN_SECONDS``).
    runs : int
        Runs of the rig's digital twin (``monitor.commission.commission``).
    on_written : callable
        Called (on the node's loop) after a file is written: the node rescans its ranges directory.
    """

    def __init__(self, ranges_dir: RangesDir, seconds: float, runs: int = 60,
                 on_written: Callable[[], None] | None = None, wall=time.gmtime):
        from monitor.commission import MIN_SECONDS

        if not seconds >= MIN_SECONDS:
            raise ValueError(f"commissioning needs at least {MIN_SECONDS:g} s of a rig's samples; got {seconds!r}")
        self.dir, self.seconds, self.runs = Path(ranges_dir.path), float(seconds), int(runs)
        self.on_written, self.wall = on_written, wall
        self._seen: set[str] = set()
        self._collecting: set[str] = set()
        self._running: dict[str, threading.Thread] = {}
        self._results: dict[str, tuple[object, str | None]] = {}  # rig -> (ranges or None, error)

    def check(self, core: MonitorCore) -> None:
        """Start, feed and finish commissionings (call from the node's loop, between batches)."""
        for rig_id in core.rigs:
            if rig_id not in self._seen:
                self._seen.add(rig_id)
                ranges, _ = core.ranges_of(rig_id)
                if ranges is None and not (self.dir / f"{rig_id}.json").exists():
                    core.tap(rig_id)
                    core.verdicts.commissioning.add(core.rigs[rig_id].row)
                    self._collecting.add(rig_id)
                    log.warning("rig %s: no ranges for it: COMMISSIONING it from its first %g s, taking it as new "
                                "(a rig already worn would be graded relative to its worn state)", rig_id, self.seconds)
        for rig_id in list(self._collecting):
            if rig_id not in core.rigs:  # forgotten meanwhile
                self._collecting.discard(rig_id)
                continue
            kept = core.tapped(rig_id)
            if len(kept) >= self.seconds * core.fleet.sample_rate:
                core.tapped(rig_id, take=True)
                self._collecting.discard(rig_id)
                config = core.rigs[rig_id].config or core.configs.get(rig_id)
                t = threading.Thread(target=self._commission, args=(rig_id, kept, config), daemon=True,
                                     name=f"commission-{rig_id}")
                self._running[rig_id] = t
                t.start()
        for rig_id, t in list(self._running.items()):
            if t.is_alive():
                continue
            del self._running[rig_id]
            ranges, error = self._results.pop(rig_id, (None, "the commissioning thread ended without a result"))
            row = core.rigs[rig_id].row if rig_id in core.rigs else None
            if row is not None:
                core.verdicts.commissioning.discard(row)
            if error is not None:
                log.error("rig %s: commissioning failed, the rig stays ungraded: %s", rig_id, error)
                continue
            path = self.dir / f"{rig_id}.json"
            tmp = path.with_name(f".{path.name}.tmp")
            try:
                ranges.save(tmp)
                os.replace(tmp, path)
            except OSError as exc:
                tmp.unlink(missing_ok=True)
                log.error("rig %s: its commissioned ranges could not be written to %s: %s", rig_id, path, exc)
                continue
            left = f"; left ungraded: {', '.join(sorted(ranges.ungraded))}" if ranges.ungraded else ""
            log.warning("rig %s: COMMISSIONED from its first %g s: ranges written to %s%s", rig_id, self.seconds,
                        path, left)
            if self.on_written is not None:
                self.on_written()

    @property
    def seen(self) -> int:
        """Rigs looked at so far."""
        return len(self._seen)

    def busy(self) -> bool:
        """Commissionings still collecting or running."""
        return bool(self._collecting or self._running)

    def _commission(self, rig_id: str, kept: np.ndarray, config) -> None:
        from hydromon.contract import RigConfig
        from monitor.commission import commission

        config = config or RigConfig()
        dt = 1.0 / config.sample_rate
        restarts = (np.flatnonzero(np.diff(kept[:, 0]) > 1.5 * dt) + 1).tolist()
        created = time.strftime("%Y-%m-%dT%H:%M:%SZ", self.wall())
        try:
            c = commission(kept[:, 1:], config, restarts=restarts, runs=self.runs,
                           made_on=f"the live monitor: the first {len(kept) / config.sample_rate:g} s of rig {rig_id}",
                           created=created)
            self._results[rig_id] = (c.ranges, None)
        except ValueError as exc:
            self._results[rig_id] = (None, str(exc))
        except Exception as exc:  # noqa: BLE001 - a failed commissioning must not end the monitor
            self._results[rig_id] = (None, f"{type(exc).__name__}: {exc}")
