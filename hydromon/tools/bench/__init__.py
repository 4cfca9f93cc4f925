"""The performance figures of ``hydromon bench``, measured in one run (targets in docs/performance.md).

Each ``bench_*`` function measures one figure and returns plain numbers; :func:`run_bench`
collects them into a :class:`BenchResult` (present it with :func:`to_json` / the CLI's table).
Throughputs are samples per second of wall time (``time.perf_counter``), the median of
``repeats`` timed passes after an untimed warm-up pass (so numba compilation and caches are
not counted). This is the shell: it reads clocks, spawns processes and opens sockets.

Figures
-------
core_single
    ``Fleet.update`` of one rig over a 60 s paper-var run, fed one sample per call (as a live
    subscriber hands them over: the headline) and in batches of 100.
core_batch
    1000 rigs, one sample per rig per tick, one ``Fleet.update`` per tick (batches of 1000),
    the fleet's rigs split over as many threads as the machine has cores (the one-thread
    figure is in the details).
replay_direct
    A simulated recording of 10 rigs in an in-memory MCAP: read, decode, validate and grade as
    fast as possible through ``hydromon.engine.core.MonitorCore`` (the ``replay --direct``
    path); ``pydantic`` + ``Fleet.update`` alone is reported beside it.
baseline_naive
    ``monitor.reference``: the same identification per sample in plain numpy (no numba, no
    batching), for one rig, on the same run as core_single. It does no read-out or grading,
    so the speed-up over core_single is a lower bound.
memory_per_rig
    Fleet state bytes per rig (array nbytes / capacity) and the RSS growth of 10,000 rigs,
    in a fresh process.
transport_ceiling
    The ceiling of ``live``: ``hydromon sim --rate 0`` (live's publisher and messages, 1000
    rigs, as fast as it can) over loopback TCP to a bare subscriber process that only drains a
    FIFO channel; messages/s received. ``raw`` in the details: the same subscriber fed by a
    zenoh-python loop of pre-built payloads (what zenoh-python itself carries here).
live
    ``hydromon sim --rate 1 --frame N`` (frames of N samples, default 10) and ``hydromon monitor``
    as separate processes, stepping up the rig count (:func:`bench_live`, :func:`live_step`): the
    largest count with no sample lost, every health message on time and p99 latency < 50 ms
    (from the deadline of the last sample of the frame that carried the graded sample).
    ``live_samples``: the same with one message per sample.
kernel_us_per_sample
    The compiled pipeline alone on one thread: 1e6 / core_batch's one-thread figure [us].
monitor_us_per_sample
    The monitor process's CPU time per sample graded in live's best step [us] (all its
    threads: zenoh's receive thread, decoding, the kernel, health).
replay_direct_framed
    replay_direct of the same recording written as frames of N samples.
replay_direct_framed_jobs
    The same in one process per core (``replay --direct --jobs``), the rigs split between them.

Every figure shares the machine with whatever else runs on it; the load average is recorded
with each run (``machine.loadavg_1min*``, per live step ``loadavg_1min``).
"""

from __future__ import annotations

from .core import (bench_core_batch, bench_core_single, bench_identify_single, bench_memory, bench_naive,
                   bench_replay_direct, paper_var_samples)
from .live import bench_live, live_step
from .run import BenchOptions, BenchResult, append_history, machine_info, run_bench, to_json
from .transport import bench_transport

__all__ = [
    "BenchResult", "BenchOptions", "paper_var_samples", "bench_core_single", "bench_core_batch",
    "bench_replay_direct", "bench_naive", "bench_identify_single", "bench_memory", "bench_transport",
    "bench_live", "live_step", "machine_info", "run_bench", "to_json", "append_history",
]
