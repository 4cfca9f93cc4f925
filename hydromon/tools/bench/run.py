"""One ``hydromon bench`` run: every figure, the machine, the JSON and the history file."""

from __future__ import annotations

import datetime as _dt
import os
import platform
from dataclasses import asdict, dataclass, field

import numpy as np
import orjson

from .core import (bench_core_batch, bench_core_single, bench_identify_single, bench_memory, bench_naive,
                   bench_replay_direct, paper_var_samples)
from .live import bench_live
from .procs import _log
from .transport import bench_transport


def machine_info() -> dict:
    import numba

    info = {"platform": platform.platform(), "machine": platform.machine(), "cpu_count": os.cpu_count(),
            "python": platform.python_version(), "numpy": np.__version__, "numba": numba.__version__,
            "loadavg_1min": os.getloadavg()[0]}  # other work on the machine skews every figure
    from importlib.metadata import PackageNotFoundError, version
    for dist in ("eclipse-zenoh", "mcap", "pydantic", "orjson"):
        try:
            info[dist.removeprefix("eclipse-")] = version(dist)
        except PackageNotFoundError:  # pragma: no cover
            info[dist.removeprefix("eclipse-")] = None
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    info["cpu"] = line.split(":", 1)[1].strip()
                    break
    except OSError:  # pragma: no cover
        pass
    return info


@dataclass
class BenchResult:
    """Every figure of one run (throughputs in samples/s; see the module docstring)."""

    core_single: float
    core_batch: float
    replay_direct: float
    live: dict | None
    transport_ceiling: float
    baseline_naive: float
    memory_per_rig: dict
    speedup_vs_naive: float
    details: dict = field(default_factory=dict)
    timestamp: str = ""
    machine: dict = field(default_factory=dict)
    kernel_us_per_sample: float | None = None   # the compiled pipeline alone, one thread [us]
    monitor_us_per_sample: float | None = None  # live's monitor CPU per sample [us] (the frames step-up)
    replay_direct_framed: float | None = None   # replay_direct of a recording of frames [samples/s]
    replay_direct_framed_jobs: float | None = None  # the same in one process per core (replay --direct --jobs)
    live_samples: dict | None = None            # live's step-up with one message per sample


@dataclass(frozen=True)
class BenchOptions:
    quick: bool = False
    live: bool = True
    live_seconds: float = 10.0
    live_steps: tuple = (100, 200, 500, 1000, 2000, 5000)
    transport_seconds: float = 5.0
    frame: int | None = 10          # samples a frame in live and replay_direct_framed (None: samples only)
    live_samples: bool = True       # also step up live with one message per sample
    monitors: int = 1               # monitor processes in the live step-up, sharded by --rigs


def run_bench(opts: BenchOptions = BenchOptions()) -> BenchResult:
    """Measure every figure (see the module docstring); progress goes to stderr."""
    q = opts.quick
    load_start = os.getloadavg()[0]
    duration = 5.0 if q else 60.0
    _log(f"simulating a {duration:g} s paper-var run")
    samples = paper_var_samples(duration)
    details: dict = {"quick": q}
    _log("core_single (batch 1)")
    s1 = bench_core_single(samples, 1, repeats=1 if q else 3)
    _log("core_single (batch 100)")
    s100 = bench_core_single(samples, 100, repeats=1 if q else 3)
    details["core_single"] = {"batch_1": s1, "batch_100": s100, "headline": "batch_1",
                              "samples": len(samples),
                              "what": "Fleet.update per call: identification, read-out and grading every "
                                      "10 samples"}
    _log("baseline_naive")
    naive_samples = samples if not q else samples[:300]
    naive = bench_naive(naive_samples, repeats=1)
    details["baseline_naive"] = {"samples": len(naive_samples),
                                 "what": "identification per sample in numpy (no read-out, no grading)"}

    _log("identify only (batch 1)")
    ident = bench_identify_single(samples, repeats=1 if q else 3)
    details["identify_single"] = {"samples_per_s": ident, "speedup_vs_naive": ident / naive,
                                  "what": "monitor.identify.fleet_step per sample: the naive baseline's "
                                          "compiled twin"}

    n_rigs, ticks = (50, 200) if q else (1000, 1000)
    _log(f"core_batch ({n_rigs} rigs x {ticks} ticks)")
    from hydromon.store.fleetfile import spread_fleet
    from hydromon.store.simfiles import iter_blocks

    # 10 distinct rigs (severities 0..1, realistic noise) tiled over the fleet
    plant = spread_fleet(10, profile="paper-var", noise="realistic").build()
    source = np.concatenate([b.samples for b in iter_blocks(plant, ticks, block=1000)], axis=1)
    threads = os.cpu_count() or 1
    cb1 = bench_core_batch(source, n_rigs, ticks, repeats=1 if q else 3)
    cb = cb1
    if threads > 1:
        _log(f"core_batch on {threads} threads")
        cb = bench_core_batch(source, n_rigs, ticks, repeats=1 if q else 3, threads=threads)
    details["core_batch"] = {"rigs": n_rigs, "ticks": ticks, "batch": n_rigs, "threads": threads,
                             "one_thread": cb1, "headline": f"{threads} threads (Fleet(threads=...))"}

    _log("replay_direct")
    rd_kw = dict(n_rigs=2 if q else 10, duration=5.0 if q else 60.0, repeats=1 if q else 3)
    rd = bench_replay_direct(**rd_kw)
    details["replay_direct"] = rd
    rdf = rdf_jobs = None
    if opts.frame is not None:
        _log(f"replay_direct of frames of {opts.frame}")
        details["replay_direct_framed"] = bench_replay_direct(**rd_kw, frame=opts.frame, jobs=threads)
        rdf = details["replay_direct_framed"]["samples_per_s"]
        rdf_jobs = details["replay_direct_framed"].get("monitor_core_jobs")

    _log("memory_per_rig")
    mem = bench_memory(1000 if q else 10_000)

    _log("transport_ceiling")
    tr = bench_transport(seconds=1.0 if q else opts.transport_seconds, n_keys=100 if q else 1000)
    details["transport_ceiling"] = tr

    live = live_samples = None

    def step_up(frame):
        if q:  # a smoke run: one small step
            return bench_live(opts.live_steps[:1], seconds=min(opts.live_seconds, 3.0), refine=0, frame=frame,
                              monitors=opts.monitors)
        return bench_live(opts.live_steps, seconds=opts.live_seconds, frame=frame, monitors=opts.monitors)

    if opts.live:
        live = step_up(opts.frame)
        if opts.frame is not None and opts.live_samples:
            live_samples = step_up(None)
    else:
        live = {"rigs": None, "reason": "skipped (--no-live)"}

    return BenchResult(
        core_single=s1, core_batch=cb, replay_direct=rd["samples_per_s"], live=live,
        transport_ceiling=tr["messages_per_s"], baseline_naive=naive, memory_per_rig=mem,
        speedup_vs_naive=s1 / naive, details={**details, "speedup_batch100_vs_naive": s100 / naive},
        timestamp=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        machine={**machine_info(), "loadavg_1min_start": load_start},
        kernel_us_per_sample=1e6 / cb1, monitor_us_per_sample=(live or {}).get("monitor_us_per_sample"),
        replay_direct_framed=rdf, replay_direct_framed_jobs=rdf_jobs, live_samples=live_samples,
    )


def to_json(result: BenchResult) -> dict:
    return asdict(result)


def append_history(result: BenchResult, path) -> None:
    """Append the run as one JSON line to ``path`` (benchmarks/history.jsonl)."""

    with open(path, "ab") as f:
        f.write(orjson.dumps(to_json(result), option=orjson.OPT_SERIALIZE_NUMPY) + b"\n")
