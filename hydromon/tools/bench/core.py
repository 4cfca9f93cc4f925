"""Core, naive, memory and replay figures of ``hydromon bench`` (see ``hydromon.tools.bench``)."""

from __future__ import annotations

import gc
import io
import multiprocessing as mp
import statistics
import time

import numpy as np


def _median_rate(n: int, fn, repeats: int) -> float:
    """Median of n / seconds over ``repeats`` timed calls of ``fn`` (after one warm-up call)."""
    fn()
    rates = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        rates.append(n / (time.perf_counter() - t))
    return float(statistics.median(rates))


def paper_var_samples(duration: float = 60.0, noise: str = "realistic", seed: int = 0) -> np.ndarray:
    """(N, 5) samples ug, x1, x3, x4, x5 (SI) of a nominal rig under the paper-var input."""
    from plant_sim.noise import noise_model
    from plant_sim.profiles import PaperVariable
    from plant_sim.simulate import simulate

    return simulate(PaperVariable(), duration, noise=noise_model(noise), seed=seed).samples


# -- core ---------------------------------------------------------------------------------------

def bench_core_single(samples: np.ndarray, batch: int, repeats: int = 3) -> float:
    """samples/s of ``Fleet.update`` for one rig fed ``batch`` samples per call."""
    from monitor.pipeline import Fleet

    if batch < 1:
        raise ValueError(f"batch {batch!r} must be >= 1")
    n = len(samples)
    rig = np.zeros(n, np.int64)
    samples = np.ascontiguousarray(samples, dtype=np.float64)
    if batch == 1:
        rows = [samples[i:i + 1] for i in range(n)]
        rigs = [rig[i:i + 1] for i in range(n)]
    else:
        rows = [samples[i:i + batch] for i in range(0, n, batch)]
        rigs = [rig[i:i + batch] for i in range(0, n, batch)]

    def one_pass():
        fleet = Fleet(capacity=1)
        fleet.add_rig("rig")
        for r, s in zip(rigs, rows):
            fleet.update(r, s)

    return _median_rate(n, one_pass, repeats)


def bench_identify_single(samples: np.ndarray, repeats: int = 3) -> float:
    """samples/s of the compiled identification kernel alone (``monitor.identify.fleet_step``),
    one call per sample for one rig: the like-for-like twin of :func:`bench_naive` (no read-out,
    no grading, no ``Fleet.update`` argument checks)."""
    from monitor.ident_options import IdentOptions, Kernels, new_state, rig_constants
    from monitor.identify import fleet_step
    from hydromon.contract import RigConfig

    k = Kernels(IdentOptions(), RigConfig().h)
    consts = rig_constants(RigConfig())[None, :]
    n = len(samples)
    samples = np.ascontiguousarray(samples, dtype=np.float64)
    rows = [samples[i:i + 1] for i in range(n)]
    rig = np.zeros(1, np.int64)

    def one_pass():
        states = new_state(k.hyper)[None, :]
        for s in rows:
            fleet_step(states, consts, k.hyper, k.m_f, k.m_c, k.m_o, k.g_f, k.g_c, rig, s)

    return _median_rate(n, one_pass, repeats)


def bench_core_batch(source: np.ndarray, n_rigs: int = 1000, ticks: int = 1000, repeats: int = 3,
                     threads: int = 1) -> float:
    """samples/s of ``Fleet.update`` on ``n_rigs`` rigs, one sample per rig per tick, the fleet
    splitting each tick over ``threads`` threads.

    ``source`` (n_src, N, 5): distinct runs tiled over the rigs (rig r plays run r % n_src).
    """
    from monitor.pipeline import Fleet

    n_src, n, _ = source.shape
    if ticks > n:
        raise ValueError(f"ticks {ticks} > samples per source run {n}")
    # (ticks, n_rigs, 5), built before timing: the batch as a subscriber would hand it over
    blocks = np.ascontiguousarray(source[np.arange(n_rigs) % n_src][:, :ticks].transpose(1, 0, 2))
    rig = np.arange(n_rigs, dtype=np.int64)

    def one_pass():
        fleet = Fleet(capacity=n_rigs, threads=threads)
        for r in range(n_rigs):
            fleet.add_rig(f"rig-{r}")
        for k in range(ticks):
            fleet.update(rig, blocks[k])

    return _median_rate(n_rigs * ticks, one_pass, repeats)


def bench_naive(samples: np.ndarray, repeats: int = 1) -> float:
    """samples/s of ``monitor.reference.NaiveIdentifier`` (plain numpy per sample) on one rig."""
    from monitor.reference import NaiveIdentifier

    def one_pass():
        ident = NaiveIdentifier()
        for row in samples:
            ident.update(row)

    return _median_rate(len(samples), one_pass, repeats)


# -- memory -------------------------------------------------------------------------------------

def _rss_bytes() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmRSS in /proc/self/status")


def _memory_worker(n_rigs: int, out) -> None:
    from monitor.pipeline import Fleet

    warm = Fleet()  # imports and compiled kernels (numba, LLVM) loaded before the baseline
    warm.add_rig("warm")
    warm.update(np.zeros(20, np.int64), np.tile([2.0, 0.0, 6e6, 6e6, 0.0], (20, 1)))
    del warm
    gc.collect()
    rss0 = _rss_bytes()
    fleet = Fleet()
    for r in range(n_rigs):
        fleet.add_rig(f"rig-{r:05d}")
    fleet.update(np.arange(n_rigs, dtype=np.int64), np.tile([2.0, 0.0, 6e6, 6e6, 0.0], (n_rigs, 1)))
    gc.collect()
    rss1 = _rss_bytes()
    cap = fleet.states.shape[0]
    nbytes = fleet.states.nbytes + fleet.consts.nbytes + fleet.counts.nbytes + fleet.bands.nbytes
    out.put({"state_bytes": nbytes / cap, "rss_bytes": (rss1 - rss0) / n_rigs, "rigs": n_rigs,
             "capacity": cap, "array_bytes_per_rig": nbytes / n_rigs})


def bench_memory(n_rigs: int = 10_000) -> dict:
    """Fleet state bytes per rig (array nbytes / capacity) and RSS growth per rig for ``n_rigs``.

    Measured in a fresh process (so memory freed by earlier figures cannot hide growth). The
    RSS figure includes the ids, the index and the over-allocation of capacity doubling, after
    one update of every rig (so every page is touched).
    """
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=_memory_worker, args=(n_rigs, q), daemon=True)
    p.start()
    try:
        return q.get(timeout=300)
    finally:
        p.join(timeout=30)


# -- replay -------------------------------------------------------------------------------------

def _get_while_alive(q, p, timeout: float):
    """The result a worker process puts on ``q``; RuntimeError when it dies first or takes longer
    than ``timeout`` [s]."""
    import queue

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            return q.get(timeout=1.0)
        except queue.Empty:
            if not p.is_alive():
                raise RuntimeError(f"bench worker died (exit status {p.exitcode})") from None
    raise RuntimeError(f"bench worker gave no result in {timeout:g} s")


def _replay_pass(data: bytes, n_samples: int, jobs: int = 1) -> None:
    """``hydromon replay --direct [--jobs N]``'s path over the in-memory recording ``data``, its
    batching; raises unless every one of its ``n_samples`` samples was taken."""
    from hydromon.store.replay_jobs import replay_direct_jobs

    _, core = replay_direct_jobs(io.BytesIO(data), jobs=jobs)
    if core.counters.accepted != n_samples:
        raise RuntimeError(f"replay accepted {core.counters.accepted} samples, expected {n_samples}")


def _replay_jobs_worker(data: bytes, n_samples: int, jobs: int, repeats: int, out) -> None:
    out.put({"monitor_core_fresh": _median_rate(n_samples, lambda: _replay_pass(data, n_samples), repeats),
             "monitor_core_jobs": _median_rate(n_samples, lambda: _replay_pass(data, n_samples, jobs), repeats)})


def bench_replay_direct(n_rigs: int = 10, duration: float = 60.0, repeats: int = 3, frame: int | None = None,
                        jobs: int = 1) -> dict:
    """samples/s of a recording (in-memory MCAP) read, decoded, validated and graded.

    With ``frame`` N the recording holds frames of N samples (``hydromon sim --to-mcap --frame N``)
    and only the ``monitor_core`` path is measured. With ``jobs`` > 1 it is measured too in a
    fresh process, as ``replay --direct`` runs, in one process (``monitor_core_fresh``) and in
    ``jobs`` (``monitor_core_jobs``: ``replay --direct --jobs``, the rigs split between them).

    Two paths over the same ``hydromon sim --to-mcap``-style recording of ``n_rigs`` rigs:
    ``monitor_core`` (the headline): :func:`hydromon.store.replay.replay_direct`, the path of
    ``hydromon replay --direct`` (reading, edge validation, seq checks, Fleet.update, health payloads);
    ``pydantic``: ``Sample.model_validate_json`` per message into ``Fleet.update`` (no health
    payloads), used as the headline when there is no monitor node.
    """
    from hydromon.contract import Sample
    from hydromon.store.fleetfile import spread_fleet
    from hydromon.store.mcap_layout import rig_topic
    from hydromon.store.mcap_read import read_recording
    from hydromon.store.simfiles import write_mcap
    from monitor.pipeline import Fleet

    spec = spread_fleet(n_rigs, profile="paper-var", noise="realistic")
    buf = io.BytesIO()
    write_mcap(spec, duration, buf, frame=frame)
    data = buf.getvalue()
    n_samples = n_rigs * int(round(duration * 100.0))
    chunk = 4096

    def pydantic_pass():
        fleet = Fleet(capacity=n_rigs)
        index = {rid: fleet.add_rig(rid) for rid in spec.ids}
        rig = np.empty(chunk, np.int64)
        rows = np.empty((chunk, 5))
        m = 0
        count = 0
        for key, payload, _, _ in read_recording(io.BytesIO(data)):
            parsed = rig_topic(key)
            if parsed is None or parsed[1] != "sample":
                continue
            s = Sample.model_validate_json(payload)
            rig[m] = index[parsed[0]]
            rows[m] = (s.ug, s.x1, s.x3, s.x4, s.x5)
            m += 1
            if m == chunk:
                fleet.update(rig, rows)
                count += m
                m = 0
        if m:
            fleet.update(rig[:m], rows[:m])
            count += m
        if count != n_samples:
            raise RuntimeError(f"replay read {count} samples, expected {n_samples}")

    out = {"rigs": n_rigs, "samples": n_samples, "mcap_bytes": len(data), "frame": frame}
    if frame is None:
        out["pydantic"] = _median_rate(n_samples, pydantic_pass, repeats)
    try:
        from hydromon.engine.core import MonitorCore
    except ImportError:
        MonitorCore = None
    if MonitorCore is not None:
        out["monitor_core"] = _median_rate(n_samples, lambda: _replay_pass(data, n_samples), repeats)
        if jobs > 1:
            # as `replay --direct --jobs` runs: from a fresh process (forking this one, with the
            # other figures' memory, costs more), against one job in that same process
            ctx = mp.get_context("spawn")
            q = ctx.Queue()
            # not a daemon: it forks the replay's workers
            p = ctx.Process(target=_replay_jobs_worker, args=(data, n_samples, jobs, repeats, q))
            p.start()
            try:
                got = _get_while_alive(q, p, 600.0)
            finally:
                p.join(timeout=30)
                if p.is_alive():
                    p.kill()
            out.update(jobs=jobs, **got)
    out["samples_per_s"] = out.get("monitor_core", out.get("pydantic"))
    out["via"] = "monitor_core" if "monitor_core" in out else "pydantic"
    return out
