"""Compile, before a node subscribes, every kernel its first messages would otherwise wait for.

On a fresh machine numba compiles a kernel on its first use: the pipeline's on a dummy record
(``monitor.pipeline.warm_up``, about a minute), and then, on the first batch a monitor core
grades, the engine's own, the health writer among them (7.6 s more, measured with an empty
``NUMBA_CACHE_DIR``). A node that compiled those inside its loop would let its first samples
queue behind the compiler, and the bus drop what no longer fits behind them.
"""

from __future__ import annotations

from hydromon.contract import frame_key, sample_key
from hydromon.engine.core import MonitorCore
from hydromon.engine.frames import frame_payload
from hydromon.engine.samples import sample_payload
from monitor.pipeline import warm_up as warm_up_pipeline

__all__ = ["warm_up"]

_WORKING_POINT = (2.0, 0.01, 6e6, 5e6, 1e-5)  # ug [V], x1 [m], x3, x4 [Pa], x5 [m] near a working point


def _row(seq: int) -> list:
    ug, x1, x3, x4, x5 = _WORKING_POINT
    return [ug + 0.1 * (seq % 7), x1 + 1e-4 * (seq % 17), x3 + 1e4 * (seq % 5), x4 - 1e4 * (seq % 3),
            x5 * (1 + seq % 4)]


def warm_up(samples: int = 40) -> None:
    """Compile the pipeline's kernels and a monitor core's (samples, frames, health payloads) on
    ``samples`` dummy samples of one rig sent one by one and of another sent in frames of 10."""
    warm_up_pipeline()
    core = MonitorCore(eval_every=10)
    h = 1.0 / MonitorCore.SAMPLE_RATE  # [s]
    messages = [(sample_key("warm-up-samples"), sample_payload(k, k * h, _row(k))) for k in range(samples)]
    for k0 in range(0, samples, 10):
        ks = range(k0, min(k0 + 10, samples))
        columns = [list(c) for c in zip(*(_row(k) for k in ks))]
        messages.append((frame_key("warm-up-frames"), frame_payload(k0, [k * h for k in ks], columns)))
    core.process(messages)
    core.process(messages[-1:])  # a lone message takes its own path
