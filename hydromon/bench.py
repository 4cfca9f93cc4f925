"""The performance figures of ``hydromon bench`` (issue 5), measured in one run.

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
    fast as possible through ``hydromon.monitornode.MonitorCore`` (the ``replay --direct``
    path); ``pydantic`` + ``Fleet.update`` alone is reported beside it.
baseline_naive
    ``hydromon.naive``: the same identification per sample in plain numpy (no numba, no
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
    ``hydromon sim --rate 1`` and ``hydromon monitor`` as separate processes, stepping up the
    rig count (:func:`bench_live`, :func:`live_step`): the largest count with no sample lost,
    every health message on time and p99 sample-to-health latency < 50 ms.

Every figure shares the machine with whatever else runs on it; the load average is recorded
with each run (``machine.loadavg_1min*``, per live step ``loadavg_1min``).
"""

from __future__ import annotations

import datetime as _dt
import gc
import io
import math
import multiprocessing as mp
import os
import platform
import re
import signal
import statistics
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field

import numpy as np
import orjson

__all__ = [
    "BenchResult", "paper_var_samples", "bench_core_single", "bench_core_batch", "bench_replay_direct",
    "bench_naive", "bench_identify_single", "bench_memory", "bench_transport", "machine_info", "run_bench", "to_json",
    "append_history",
]


def _log(msg: str) -> None:
    print(f"hydromon bench: {msg}", file=sys.stderr, flush=True)


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
    from monitor.identify import IdentOptions, Kernels, fleet_step, new_state, rig_constants
    from plant_sim.params import RigConfig

    k = Kernels(IdentOptions(), RigConfig().h)
    consts = rig_constants(RigConfig())[None, :]
    n = len(samples)
    samples = np.ascontiguousarray(samples, dtype=np.float64)
    rows = [samples[i:i + 1] for i in range(n)]
    rig = np.zeros(1, np.int64)

    def one_pass():
        states = new_state(k.hyper)[None, :]
        for s in rows:
            fleet_step(states, consts, k.hyper, k.m_f, k.m_c, rig, s)

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
    """samples/s of ``hydromon.naive.NaiveIdentifier`` (plain numpy per sample) on one rig."""
    from hydromon.naive import NaiveIdentifier

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

def bench_replay_direct(n_rigs: int = 10, duration: float = 60.0, repeats: int = 3) -> dict:
    """samples/s of a recording (in-memory MCAP) read, decoded, validated and graded.

    Two paths over the same ``hydromon sim --to-mcap``-style recording of ``n_rigs`` rigs:
    ``monitor_core`` (the headline): :func:`hydromon.mcap_io.read_recording` into
    ``hydromon.monitornode.MonitorCore.process`` in chunks of 4096 messages, the path of
    ``hydromon replay --direct`` (edge validation, seq checks, Fleet.update, health payloads);
    ``pydantic``: ``Sample.model_validate_json`` per message into ``Fleet.update`` (no health
    payloads), used as the headline when there is no monitor node.
    """
    from hydromon.contract import Sample
    from hydromon.fleetfile import spread_fleet
    from hydromon.mcap_io import read_recording, rig_topic
    from hydromon.simnode import write_mcap
    from monitor.pipeline import Fleet

    spec = spread_fleet(n_rigs, profile="paper-var", noise="realistic")
    buf = io.BytesIO()
    write_mcap(spec, duration, buf)
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

    out = {"rigs": n_rigs, "samples": n_samples, "mcap_bytes": len(data)}
    out["pydantic"] = _median_rate(n_samples, pydantic_pass, repeats)
    try:
        from hydromon.monitornode import MonitorCore
    except ImportError:
        MonitorCore = None
    if MonitorCore is not None:
        def core_pass():
            core = MonitorCore()
            batch = []
            for key, payload, _, _ in read_recording(io.BytesIO(data)):
                batch.append((key, payload))
                if len(batch) == chunk:
                    core.process(batch)
                    batch = []
            core.process(batch)
            if core.counters.accepted != n_samples:
                raise RuntimeError(f"replay accepted {core.counters.accepted} samples, expected {n_samples}")

        out["monitor_core"] = _median_rate(n_samples, core_pass, repeats)
    out["samples_per_s"] = out.get("monitor_core", out["pydantic"])
    out["via"] = "monitor_core" if "monitor_core" in out else "pydantic"
    return out


# -- transport ----------------------------------------------------------------------------------

def _transport_sub(endpoint: str, seconds: float, ready, out) -> None:
    import zenoh

    from hydromon.bus import open_session

    with open_session("peer", listen=[endpoint]) as session:
        sub = session.declare_subscriber("hydro/rig/*/sample", zenoh.handlers.FifoChannel(65536))
        ready.put(True)
        first = sub.recv()  # the publisher has started
        t0 = time.perf_counter()
        c0 = time.process_time()
        n = 0
        deadline = t0 + seconds
        # blocking drain: the publisher keeps sending past our window, so recv() returns
        while True:
            sub.recv()
            n += 1
            if (n & 255) == 0 and time.perf_counter() >= deadline:
                break
        dt = time.perf_counter() - t0
        out.put({"messages": n, "seconds": dt, "cpu_s": time.process_time() - c0, "first": first is not None})
        sub.undeclare()


def _transport_pub(endpoint: str, seconds: float, n_keys: int, out) -> None:
    import orjson
    import zenoh

    from hydromon.bus import JSON, open_session

    with open_session("peer", connect=[endpoint]) as session:
        pubs = [session.declare_publisher(f"hydro/rig/rig-{i:04d}/sample", encoding=JSON,
                                          congestion_control=zenoh.CongestionControl.BLOCK)
                for i in range(n_keys)]
        time.sleep(1.0)  # let the subscriber's interest arrive
        payloads = [orjson.dumps({"seq": k, "t": k * 0.01, "ug": 2.0 + 0.1 * k % 1, "x1": 0.01234567,
                                  "x3": 6123456.7, "x4": 5987654.3, "x5": 1.2345e-5}) for k in range(1000)]
        t0 = time.perf_counter()
        c0 = time.process_time()
        n = 0
        stop = t0 + seconds + 1.0
        while time.perf_counter() < stop:
            for p in payloads:
                pubs[n % n_keys].put(p)
                n += 1
        out.put({"messages": n, "seconds": time.perf_counter() - t0, "cpu_s": time.process_time() - c0})


def bench_transport(seconds: float = 5.0, n_keys: int = 100) -> dict:
    """messages/s a bare zenoh subscriber process drains from a publisher process (loopback TCP).

    Two publishers, one after the other: ``hydromon sim --rigs n_keys --rate 0`` (the live
    step's own publisher and messages, as fast as it can: the headline, the ceiling of
    ``live``), and a raw zenoh-python loop putting pre-built sample payloads (``raw``: what
    zenoh-python itself carries on this machine).
    """
    from hydromon.bus import free_tcp_endpoint

    ctx = mp.get_context("spawn")

    def measure(start_pub):
        endpoint = free_tcp_endpoint()
        ready, out_sub = ctx.Queue(), ctx.Queue()
        sub = ctx.Process(target=_transport_sub, args=(endpoint, seconds, ready, out_sub), daemon=True)
        sub.start()
        try:
            ready.get(timeout=60)
            stop_pub = start_pub(endpoint)
            try:
                rs = out_sub.get(timeout=seconds + 180)
            finally:
                pub_cpu = stop_pub()
        finally:
            sub.join(timeout=10)
            if sub.is_alive():
                sub.terminate()
        return {"messages_per_s": rs["messages"] / rs["seconds"], "messages": rs["messages"],
                "seconds": rs["seconds"], "subscriber_cpu": rs["cpu_s"] / rs["seconds"], "publisher_cpu": pub_cpu}

    def raw_pub(endpoint):
        out_pub = ctx.Queue()
        pub = ctx.Process(target=_transport_pub, args=(endpoint, seconds, n_keys, out_pub), daemon=True)
        pub.start()

        def stop():
            rp = out_pub.get(timeout=seconds + 60)
            pub.join(timeout=10)
            if pub.is_alive():
                pub.terminate()
            return rp["cpu_s"] / rp["seconds"]
        return stop

    def sim_pub(endpoint):
        sim = subprocess.Popen([sys.executable, "-m", "hydromon.cli", "sim", "--rigs", str(n_keys), "--rate", "0",
                                "--connect", endpoint], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        t0, c0 = time.perf_counter(), _cpu_seconds(sim.pid)

        def stop():
            cpu = (_cpu_seconds(sim.pid) - c0) / (time.perf_counter() - t0)
            _stop(sim)
            return cpu
        return stop

    out = measure(sim_pub)
    out.update(publisher="hydromon sim --rate 0", keys=n_keys, endpoint="tcp/127.0.0.1",
               raw=measure(raw_pub) | {"publisher": "zenoh-python loop of pre-built payloads"})
    return out


# -- the whole run ------------------------------------------------------------------------------

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


@dataclass(frozen=True)
class BenchOptions:
    quick: bool = False
    live: bool = True
    live_seconds: float = 10.0
    live_steps: tuple = (100, 200, 500, 1000, 2000, 5000)
    transport_seconds: float = 5.0


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
    from hydromon.fleetfile import spread_fleet
    from hydromon.simnode import iter_blocks

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
    rd = bench_replay_direct(n_rigs=2 if q else 10, duration=5.0 if q else 60.0, repeats=1 if q else 3)
    details["replay_direct"] = rd

    _log("memory_per_rig")
    mem = bench_memory(1000 if q else 10_000)

    _log("transport_ceiling")
    tr = bench_transport(seconds=1.0 if q else opts.transport_seconds, n_keys=100 if q else 1000)
    details["transport_ceiling"] = tr

    live = None
    if opts.live:
        if q:  # a smoke run: one small step
            live = bench_live(opts.live_steps[:1], seconds=min(opts.live_seconds, 3.0), refine=0)
        else:
            live = bench_live(opts.live_steps, seconds=opts.live_seconds)
    else:
        live = {"rigs": None, "reason": "skipped (--no-live)"}

    return BenchResult(
        core_single=s1, core_batch=cb, replay_direct=rd["samples_per_s"], live=live,
        transport_ceiling=tr["messages_per_s"], baseline_naive=naive, memory_per_rig=mem,
        speedup_vs_naive=s1 / naive, details={**details, "speedup_batch100_vs_naive": s100 / naive},
        timestamp=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        machine={**machine_info(), "loadavg_1min_start": load_start},
    )


def to_json(result: BenchResult) -> dict:
    return asdict(result)


def append_history(result: BenchResult, path) -> None:
    """Append the run as one JSON line to ``path`` (benchmarks/history.jsonl)."""
    import orjson

    with open(path, "ab") as f:
        f.write(orjson.dumps(to_json(result), option=orjson.OPT_SERIALIZE_NUMPY) + b"\n")


# -- live: hydromon sim + hydromon monitor as processes -----------------------------------------

_MON_SUMMARY = re.compile(r"(\d+) rig\(s\), (\d+) samples, (\d+) health messages; rejected: (.*); "
                          r"dropped seq (\d+), gaps (\d+) \((\d+) samples missing\)")
_SIM_SUMMARY = re.compile(r"(\d+) samples x (\d+) rig\(s\), (\d+) messages in ([\d.]+) s; max lateness ([\d.]+) ms")


def _cpu_seconds(pid: int) -> float:
    """utime + stime of a process (all its threads) [s], from /proc/<pid>/stat."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _wait_for(path: str, text: str, proc, timeout: float) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        with open(path) as f:
            if text in f.read():
                return
        if proc.poll() is not None:
            with open(path) as f:
                raise RuntimeError(f"process exited ({proc.returncode}) before {text!r}: {f.read()[-2000:]}")
        time.sleep(0.05)
    raise RuntimeError(f"timed out waiting for {text!r} in {path}")


def _stop(proc, timeout: float = 30.0) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)


def live_step(n_rigs: int, seconds: float = 10.0, warm: float = 3.0, grace: float = 1.0,
              eval_every: int = 10, h: float = 0.01, max_p99_ms: float = 50.0) -> dict:
    """Run ``hydromon sim --rigs N --rate 1`` and ``hydromon monitor`` as processes on loopback.

    Topology: this process opens a probe session listening on P; the monitor listens on A and
    connects to P; the sim connects to A and P (every pair talks directly). The probe records
    the arrival time [time.monotonic, shared by all processes] of every health message and of
    the first rig's samples. The sim sends sample k of every rig at the deadline t0 + k h, so
    t0 is estimated as min_k(arrival_k - k h) over the first rig (it exceeds the true t0 by the
    smallest transport delay, so latencies are under-stated by that, ~0.1 ms) and a health
    message's latency is its arrival minus the deadline of the sample seq it reports.

    Counted over the window [t0 + warm, t0 + warm + seconds] of deadlines (warm counted from
    the first health message when that comes later than the first sample): ``lost`` = samples
    the monitor saw missing from the seq (gaps) or dropped as duplicates/out of order (from
    its exit summary, whole run); ``health_missing`` = health messages expected (every rig,
    every ``eval_every`` samples) but not received within ``grace`` after the window.
    ``ok`` = nothing lost or missing and p99 < ``max_p99_ms``.
    """
    import tempfile

    import zenoh

    from hydromon.bus import free_tcp_endpoint, open_session

    ep_p, ep_a = free_tcp_endpoint(), free_tcp_endpoint()
    first_rig = "rig-" + "0" * max(4, len(str(n_rigs - 1)))
    samples: list = []
    health: list = []
    clock = time.monotonic

    def on_sample(s):
        samples.append((clock(), s.payload.to_bytes()))

    def on_health(s):
        health.append((clock(), s.payload.to_bytes()))

    py = [sys.executable, "-m", "hydromon.cli"]
    from hydromon.quietgc import QuietGC

    # the probe timestamps in zenoh callbacks: a garbage collection in this process would
    # delay them and count as latency; collections run in the sleeps below instead
    with tempfile.TemporaryDirectory(prefix="hydromon-bench-") as tmp, \
            open_session("peer", listen=[ep_p]) as probe, QuietGC() as quiet:
        sub_s = probe.declare_subscriber(f"hydro/rig/{first_rig}/sample", on_sample)
        sub_h = probe.declare_subscriber("hydro/rig/*/health", on_health)
        mon_log, sim_log = os.path.join(tmp, "monitor.log"), os.path.join(tmp, "sim.log")
        with open(mon_log, "w") as ml, open(sim_log, "w") as sl:
            mon = subprocess.Popen(py + ["monitor", "--listen", ep_a, "--connect", ep_p, "--node", "bench",
                                         "--eval-every", str(eval_every)], stderr=ml, stdout=subprocess.DEVNULL)
            sim = None
            try:
                _wait_for(mon_log, "hydromon monitor: node", mon, 120)
                time.sleep(1.0)  # subscribers declared and routes known
                sim = subprocess.Popen(py + ["sim", "--rigs", str(n_rigs), "--rate", "1", "--connect", ep_a,
                                             "--connect", ep_p], stderr=sl, stdout=subprocess.DEVNULL)
                end = clock() + 120
                while not samples and clock() < end:
                    if sim.poll() is not None:
                        raise RuntimeError(f"sim exited ({sim.returncode}): {open(sim_log).read()[-2000:]}")
                    time.sleep(0.01)
                if not samples:
                    raise RuntimeError("no sample reached the probe in 120 s")
                t_first = samples[0][0]
                # the window opens `warm` after the monitor's first health (kernels compiled or
                # loaded from numba's cache, routes up), and never before `warm` after the first sample
                while not health and clock() < t_first + 300:
                    if mon.poll() is not None:
                        raise RuntimeError(f"monitor exited ({mon.returncode}): {open(mon_log).read()[-1500:]}")
                    time.sleep(0.01)
                if not health:
                    raise RuntimeError("no health message reached the probe in 300 s")
                warm = max(warm, health[0][0] - t_first + warm)
                time.sleep(max(0.0, t_first + warm - clock()))
                cpu0 = (_cpu_seconds(sim.pid), _cpu_seconds(mon.pid), time.process_time(), clock())
                while clock() < t_first + warm + seconds:
                    quiet.idle()
                    time.sleep(min(0.05, max(0.0, t_first + warm + seconds - clock())))
                for name, proc, path in (("monitor", mon, mon_log), ("sim", sim, sim_log)):
                    if proc.poll() is not None:
                        raise RuntimeError(f"{name} exited ({proc.returncode}) during the window: "
                                           f"{open(path).read()[-1500:]}")
                cpu1 = (_cpu_seconds(sim.pid), _cpu_seconds(mon.pid), time.process_time(), clock())
                time.sleep(grace)
                _stop(sim)
                time.sleep(0.5)
            finally:
                if sim is not None:
                    _stop(sim)
                _stop(mon)
            sub_s.undeclare()
            sub_h.undeclare()
        mon_text, sim_text = open(mon_log).read(), open(sim_log).read()

    # t0 of the sim's deadlines, from the first rig's samples
    t0 = min(t - orjson.loads(p)["seq"] * h for t, p in samples)
    lo, hi = t0 + warm, t0 + warm + seconds
    lat = []
    for t, p in health:
        seq = orjson.loads(p)["seq"]
        dl = t0 + seq * h
        if lo <= dl < hi:
            lat.append(t - dl)
    k_lo, k_hi = math.ceil(warm / h - 1e-9), math.ceil((warm + seconds) / h - 1e-9)
    # the monitor staggers the rigs' evaluations (monitor.pipeline.eval_phase)
    from hydromon.fleetfile import spread_fleet
    from monitor.pipeline import eval_phase

    phases = [eval_phase(rid, eval_every) for rid in spread_fleet(n_rigs).ids]
    expected = sum(1 for ph in phases for k in range(k_lo, k_hi) if (k + 1 + ph) % eval_every == 0)
    lat_ms = np.array(lat) * 1e3
    # the first rig's samples at the probe: how much of the latency is the sim and the transport
    s_lat_ms = np.array([t - (t0 + orjson.loads(p)["seq"] * h) for t, p in samples
                         if lo <= t0 + orjson.loads(p)["seq"] * h < hi]) * 1e3
    m = _MON_SUMMARY.search(mon_text)
    sm = _SIM_SUMMARY.search(sim_text)
    lost = None if m is None else int(m.group(5)) + int(m.group(7))
    wall = cpu1[3] - cpu0[3]
    out = {
        "rigs": n_rigs,
        "samples_per_s": len(lat) * eval_every / seconds,
        "offered_samples_per_s": n_rigs / h,
        "lost": lost,
        "health_expected": expected,
        "health_received": len(lat),
        "health_missing": max(0, expected - len(lat)),
        "p50_ms": float(np.percentile(lat_ms, 50)) if len(lat_ms) else None,
        "p99_ms": float(np.percentile(lat_ms, 99)) if len(lat_ms) else None,
        "max_ms": float(lat_ms.max()) if len(lat_ms) else None,
        "sample_p50_ms": float(np.percentile(s_lat_ms, 50)) if len(s_lat_ms) else None,
        "sample_p99_ms": float(np.percentile(s_lat_ms, 99)) if len(s_lat_ms) else None,
        "cpu_sim": (cpu1[0] - cpu0[0]) / wall,
        "cpu_monitor": (cpu1[1] - cpu0[1]) / wall,
        "cpu_probe": (cpu1[2] - cpu0[2]) / wall,
        "seconds": seconds,
        "warm_s": warm,
        "monitor_summary": m.group(0) if m else mon_text[-500:],
        "sim_summary": sm.group(0) if sm else sim_text[-500:],
    }
    out["ok"] = bool(lost == 0 and out["health_missing"] == 0 and out["p99_ms"] is not None
                     and out["p99_ms"] < max_p99_ms)
    return out


def bench_live(steps=(100, 200, 500, 1000, 2000, 5000), seconds: float = 10.0, refine: int = 2) -> dict:
    """Step up the rig count until a step loses a sample or misses p99 < 50 ms, then bisect
    ``refine`` times between the last passing and the first failing count (to a multiple of
    10); the figure is the largest passing step (``rigs`` None with a ``reason`` if none passes
    or the monitor node is missing)."""
    try:
        import hydromon.monitornode  # noqa: F401
    except ImportError as exc:
        return {"rigs": None, "samples_per_s": None, "lost": None, "p50_ms": None, "p99_ms": None,
                "reason": f"no monitor node: {exc}"}
    results = []

    def run(n):
        _log(f"live: {n} rigs for {seconds:g} s (load average {os.getloadavg()[0]:.2f})")
        load = os.getloadavg()[0]
        try:
            r = live_step(n, seconds)
        except (RuntimeError, OSError, ValueError) as exc:
            r = {"rigs": n, "ok": False, "error": str(exc)}
        r["loadavg_1min"] = load
        _log(f"live: {n} rigs: " + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                                            for k, v in r.items() if not k.endswith("summary")))
        results.append(r)
        return r

    best, fail = None, None
    for n in steps:
        r = run(n)
        if not r.get("ok"):
            fail = n
            break
        best = r
    lo = best["rigs"] if best else 0
    broken = bool(results and "error" in results[-1])  # a crash, not a capacity limit: no bisection
    for _ in range(refine if fail is not None and not broken else 0):
        mid = int(round((lo + fail) / 2 / 10)) * 10
        if mid <= lo or mid >= fail:
            break
        r = run(mid)
        if r.get("ok"):
            best, lo = r, mid
        else:
            fail = mid
    if best is None:
        reason = f"no step passed (tried {', '.join(str(r['rigs']) for r in results)} rigs)"
        if broken:
            reason += f"; error: {results[-1]['error'][:300]}"
        return {"rigs": None, "samples_per_s": None, "lost": None, "p50_ms": None, "p99_ms": None,
                "reason": reason, "steps": results}
    out = {k: best.get(k) for k in ("rigs", "samples_per_s", "lost", "p50_ms", "p99_ms", "cpu_sim",
                                    "cpu_monitor", "cpu_probe", "health_missing", "seconds", "loadavg_1min")}
    out["limited_by"] = (f"{fail} rigs failed" + (" (error)" if broken else "") if fail is not None
                         else f"largest step tried ({steps[-1]} rigs)")
    out["steps"] = results
    return out
