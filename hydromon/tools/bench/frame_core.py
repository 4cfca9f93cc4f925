"""The monitor core's CPU per sample with frames and with one message per sample, A/B interleaved.

``python -m hydromon.tools.bench.frame_core [RIGS] [FRAME] [ROUNDS]`` (default 3000 rigs, frames of
10, 2 rounds) builds what ``hydromon sim`` would publish for 3 s of a spread fleet (paper-var,
realistic noise), both ways, and times ``MonitorCore.process`` over it in batches of 10 ms of
samples (what a live monitor drains per poll at 100 Hz: RIGS samples, or RIGS / FRAME frames;
CPU time, ``time.process_time``), after the first 0.2 s of samples (new rigs). It prints, per round and way, the load average, the core's us a sample and the share
of it in ``Fleet.update`` (the compiled pipeline).
"""

from __future__ import annotations

import os
import sys
import time

import orjson

from hydromon.contract import config_key, frame_key, sample_key
from hydromon.engine.core import MonitorCore
from hydromon.engine.frames import block_frames
from hydromon.engine.samples import sample_payload
from hydromon.store.fleetfile import spread_fleet
from hydromon.store.simfiles import iter_blocks


def messages(spec, seconds: float, frame: int | None) -> list[tuple[str, bytes]]:
    """What the sim node publishes for ``spec`` over ``seconds`` [s]: configs, then samples rig by
    rig each tick (``frame``: a frame of that many samples per rig every that many ticks)."""
    fleet = spec.build()
    msgs = [(config_key(i), orjson.dumps(c.model_dump(mode="json"))) for i, c in zip(spec.ids, fleet.configs)]
    for blk in iter_blocks(fleet, int(round(seconds / fleet.h)), block=100):
        if frame is not None:
            for j0 in range(0, len(blk.t), frame):
                keys = (frame_key(i) for i in spec.ids)
                msgs += zip(keys, block_frames(blk, j0, min(j0 + frame, len(blk.t))))
            continue
        rows = blk.samples.tolist()
        for j, (seq, t) in enumerate(zip(blk.seq.tolist(), blk.t.tolist())):
            msgs += [(sample_key(i), sample_payload(seq, t, rows[r][j])) for r, i in enumerate(spec.ids)]
    return msgs


def measure(msgs: list, n_rigs: int, per_poll: int, skip: int) -> tuple[float, float]:
    """``(us a sample in MonitorCore.process, us of it in Fleet.update)``, CPU time."""
    core = MonitorCore()
    core.process(msgs[:skip])
    before = core.counters.accepted
    spent = [0.0]
    update = core.fleet.update

    def timed(rows, vals):
        t0 = time.process_time()
        ev = update(rows, vals)
        spent[0] += time.process_time() - t0
        return ev

    core.fleet.update = timed
    t0 = time.process_time()
    for i in range(skip, len(msgs), per_poll):
        core.process(msgs[i:i + per_poll])
    n = core.counters.accepted - before
    return (time.process_time() - t0) / n * 1e6, spent[0] / n * 1e6


def main(argv: list[str]) -> int:
    n_rigs, frame, rounds = (int(a) for a in (argv + ["3000", "10", "2"][len(argv):]))
    spec = spread_fleet(n_rigs, profile="paper-var", noise="realistic")
    ways = {f"frames of {frame}": (messages(spec, 3.0, frame), frame), "samples": (messages(spec, 3.0, None), 1)}
    for r in range(rounds):
        for name, (msgs, per_msg) in ways.items():
            per_poll = max(1, n_rigs // per_msg)  # 10 ms of samples at 100 Hz, either way
            skip = n_rigs + n_rigs * 20 // per_msg  # the configs and the first 0.2 s
            core_us, kernel_us = measure(msgs, n_rigs, per_poll, skip)
            print(f"round {r + 1} load {os.getloadavg()[0]:.1f} {name:14s} core {core_us:.2f} us/sample, "
                  f"Fleet.update {kernel_us:.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
