"""``live`` of ``hydromon bench``: ``hydromon sim`` and ``hydromon monitor`` as processes, stepped up."""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
import time
from collections import Counter

import numpy as np
import orjson

from hydromon.store.fleetfile import spread_fleet

from .procs import _cpu_seconds, _log, _stop, _wait_for

_MON_SUMMARY = re.compile(r"(\d+) rig\(s\), (\d+) samples, (\d+) health messages; rejected: (.*); "
                          r"dropped seq (\d+), gaps (\d+) \((\d+) samples missing\)")
_SIM_SUMMARY = re.compile(r"(\d+) samples x (\d+) rig\(s\), (\d+) messages in ([\d.]+) s; max lateness ([\d.]+) ms")


def shard_ids(n_rigs: int, monitors: int) -> list[str]:
    """The live step's rig ids: ``rig-0000`` .. for one monitor; for K monitors ``m<k>-rig-0000`` ..,
    rig i in shard i mod K (so every shard holds rigs of every severity), graded by the monitor
    started with ``--rigs m<k>-*``."""
    ids = spread_fleet(n_rigs).ids
    return ids if monitors == 1 else [f"m{i % monitors}-{rid}" for i, rid in enumerate(ids)]


class _HealthDrain:
    """Every health message at the probe, taken from a FIFO channel by a thread that stamps each
    with the clock when it takes it (after its arrival: a latency is over-stated by at most the
    thread's 1 ms nap and its turn for the GIL, never under-stated). A Python callback per
    message, a GIL hand-over each, made the probe the bottleneck at 1500 rigs (the monitor's
    puts blocked behind it)."""

    def __init__(self, session, clock, out: list, key: str = "hydro/rig/*/health"):
        import threading

        import zenoh

        self.sub = session.declare_subscriber(key, zenoh.handlers.FifoChannel(1 << 20))
        self.clock, self.out = clock, out
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name="bench-health-drain", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        take, clock, append = self.sub.try_recv, self.clock, self.out.append
        while True:
            while (m := take()) is not None:
                append((clock(), m.payload.to_bytes(), str(m.key_expr)))
            if self.stop.wait(0.001):
                break

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5.0)
        self.sub.undeclare()


def live_step(n_rigs: int, seconds: float = 10.0, warm: float = 3.0, grace: float = 1.0,
              eval_every: int = 10, h: float = 0.01, max_p99_ms: float = 50.0,
              monitor_args: tuple = (), sim_args: tuple = (), frame: int | None = None, monitors: int = 1) -> dict:
    """Run ``hydromon sim --rigs N --rate 1`` (with ``frame``: ``--frame N``) and ``hydromon monitor``
    as processes on loopback; with ``monitors`` K > 1, K monitors sharded by ``--rigs m<k>-*``
    against one sim of the same N rigs (:func:`shard_ids`, a fleet file).

    Topology: this process opens a probe session listening on P; each monitor listens on its A and
    connects to P; the sim connects to every A and to P (every pair talks directly). The probe records
    the arrival time [time.monotonic, shared by all processes] of every health message and of
    the first rig's samples (the health messages: when the probe's drain thread takes them,
    :class:`_HealthDrain`). The sim sends sample k of every rig at the deadline t0 + k h, so
    t0 is estimated as min_k(arrival_k - k h) over the first rig (it exceeds the true t0 by the
    smallest transport delay, so latencies are under-stated by that, ~0.1 ms) and a health
    message's latency is its arrival minus the deadline of the sample seq it reports. With frames,
    the probe takes the first rig's frames (a frame is sent when its last sample is due) and a
    health message's latency is counted from the deadline of the last sample of the frame that
    holds the sample it reports (it could not be computed before that frame was sent; a rig's
    frames end at its phase, ``hydromon.bus.framer``).
    ``monitor_us_per_sample`` is the monitors' CPU time (all their threads) in the window per sample
    they graded there [us].

    Counted over the window [t0 + warm, t0 + warm + seconds] of deadlines (warm counted from
    the first health message when that comes later than the first sample): ``lost`` = samples
    the monitor saw missing from the seq (gaps) or dropped as duplicates/out of order (from
    its exit summary, whole run); ``health_missing`` = health messages expected (every rig,
    every ``eval_every`` samples) but not received within ``grace`` after the window.
    ``ok`` = nothing lost or missing and p99 < ``max_p99_ms``.
    """
    import tempfile

    from hydromon.bus.session import listening_session, on_a_free_port

    if monitors < 1:
        raise ValueError(f"monitors {monitors!r} must be >= 1")
    ids = shard_ids(n_rigs, monitors)
    first_rig = ids[0]
    samples: list = []
    health: list = []
    clock = time.monotonic

    def on_sample(s):
        samples.append((clock(), s.payload.to_bytes()))

    py = [sys.executable, "-m", "hydromon.cli"]
    from hydromon.store.quietgc import QuietGC

    # the probe timestamps in zenoh callbacks: a garbage collection in this process would
    # delay them and count as latency; collections run in the sleeps below instead
    with tempfile.TemporaryDirectory(prefix="hydromon-bench-") as tmp, \
            listening_session("peer") as (probe, ep_p), QuietGC() as quiet:
        leaf = "sample" if frame is None else "frame"
        sub_s = probe.declare_subscriber(f"hydro/rig/{first_rig}/{leaf}", on_sample)
        drain = _HealthDrain(probe, clock, health)
        mon_logs = [os.path.join(tmp, f"monitor{k}.log") for k in range(monitors)]
        sim_log = os.path.join(tmp, "sim.log")
        fleet_args = ()
        if monitors > 1:
            spec = spread_fleet(n_rigs)
            spec = spec.model_copy(update={"rigs": [r.model_copy(update={"id": i}) for r, i in zip(spec.rigs, ids)]})
            fleet_path = os.path.join(tmp, "fleet.json")
            with open(fleet_path, "w") as f:
                f.write(spec.model_dump_json(exclude_none=True))
            fleet_args = ("--fleet", fleet_path)
        mons, endpoints = [], []
        with open(sim_log, "w") as sl:
            def start_monitor(k, ml):
                def start(ep_a):
                    shard = () if monitors == 1 else ("--rigs", f"m{k}-*")
                    mon = subprocess.Popen(py + ["monitor", "--listen", ep_a, "--connect", ep_p, "--node", f"bench{k}",
                                                 "--eval-every", str(eval_every), *shard, *monitor_args],
                                           stderr=ml, stdout=subprocess.DEVNULL)
                    try:
                        _wait_for(mon_logs[k], "hydromon monitor: node", mon, 120)
                    except BaseException:
                        _stop(mon)
                        raise
                    return mon
                return start

            sim = None
            try:
                # each A: a port found free a moment ago, again on another if it was taken before the
                # monitor bound it (the monitor exits: "Address already in use")
                for k in range(monitors):
                    with open(mon_logs[k], "w") as ml:
                        mon, ep_a = on_a_free_port(start_monitor(k, ml))
                    mons.append(mon)
                    endpoints.append(ep_a)
                time.sleep(1.0)  # subscribers declared and routes known
                framing = () if frame is None else ("--frame", str(frame))
                rigs = fleet_args or ("--rigs", str(n_rigs))
                connect = [a for ep in endpoints for a in ("--connect", ep)]
                sim = subprocess.Popen(py + ["sim", *rigs, "--rate", "1", *connect, "--connect", ep_p, *framing,
                                             *sim_args], stderr=sl, stdout=subprocess.DEVNULL)
                end = clock() + 120
                while not samples and clock() < end:
                    if sim.poll() is not None:
                        raise RuntimeError(f"sim exited ({sim.returncode}): {open(sim_log).read()[-2000:]}")
                    time.sleep(0.01)
                if not samples:
                    raise RuntimeError("no sample reached the probe in 120 s")
                t_first = samples[0][0]
                # the window opens `warm` after the monitors' first health (kernels compiled or
                # loaded from numba's cache, routes up), and never before `warm` after the first sample
                while not health and clock() < t_first + 300:
                    for k, mon in enumerate(mons):
                        if mon.poll() is not None:
                            raise RuntimeError(f"monitor exited ({mon.returncode}): {open(mon_logs[k]).read()[-1500:]}")
                    time.sleep(0.01)
                if not health:
                    raise RuntimeError("no health message reached the probe in 300 s")
                warm = max(warm, health[0][0] - t_first + warm)
                time.sleep(max(0.0, t_first + warm - clock()))
                cpu0 = (_cpu_seconds(sim.pid), sum(map(_cpu_seconds, (m.pid for m in mons))), time.process_time(),
                        clock())
                while clock() < t_first + warm + seconds:
                    quiet.idle()
                    time.sleep(min(0.05, max(0.0, t_first + warm + seconds - clock())))
                for name, proc, path in [*(("monitor", m, lg) for m, lg in zip(mons, mon_logs)), ("sim", sim, sim_log)]:
                    if proc.poll() is not None:
                        raise RuntimeError(f"{name} exited ({proc.returncode}) during the window: "
                                           f"{open(path).read()[-1500:]}")
                cpu1 = (_cpu_seconds(sim.pid), sum(map(_cpu_seconds, (m.pid for m in mons))), time.process_time(),
                        clock())
                time.sleep(grace)
                _stop(sim)
                time.sleep(0.5)
            finally:
                if sim is not None:
                    _stop(sim)
                for mon in mons:
                    _stop(mon)
            sub_s.undeclare()
            drain.close()
        mon_texts, sim_text = [open(path).read() for path in mon_logs], open(sim_log).read()

    # t0 of the sim's deadlines, from the first rig's samples (frames: sent at their last one's)
    first = [(t, _last_seq(orjson.loads(p))) for t, p in samples]  # the first rig's (arrival, seq)
    t0 = min(t - k * h for t, k in first)
    # the sample that ended the frame holding seq: each rig's frames end at its phase (hydromon.bus.framer)
    from monitor.evaluations import eval_phase

    phase = {}

    def sent(key: str, seq: int) -> int:
        if frame is None:
            return seq
        rig = key.split("/")[-2]
        if rig not in phase:
            phase[rig] = eval_phase(rig, frame)
        return seq + (-(seq + 1 + phase[rig])) % frame
    lo, hi = t0 + warm, t0 + warm + seconds
    lat, late = [], Counter()
    for t, p, key in health:
        seq = orjson.loads(p)["seq"]
        dl = t0 + sent(key, seq) * h
        if lo <= dl < hi:
            lat.append(t - dl)
            if t - dl >= max_p99_ms * 1e-3:
                late[int(dl - lo)] += 1
    k_lo, k_hi = math.ceil(warm / h - 1e-9), math.ceil((warm + seconds) / h - 1e-9)
    # the monitor staggers the rigs' evaluations (monitor.evaluations.eval_phase): count per phase
    phases = Counter(eval_phase(rid, eval_every) for rid in ids)
    expected = sum(n * sum(1 for k in range(k_lo, k_hi) if (k + 1 + ph) % eval_every == 0)
                   for ph, n in phases.items())
    lat_ms = np.array(lat) * 1e3
    # the first rig's samples at the probe: how much of the latency is the sim and the transport
    s_lat_ms = np.array([t - (t0 + k * h) for t, k in first if lo <= t0 + k * h < hi]) * 1e3
    ms = [_MON_SUMMARY.search(text) for text in mon_texts]
    sm = _SIM_SUMMARY.search(sim_text)
    lost = None if None in ms else sum(int(m.group(5)) + int(m.group(7)) for m in ms)
    wall = cpu1[3] - cpu0[3]
    out = {
        "rigs": n_rigs,
        "frame": frame,
        "monitors": monitors,
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
        # per sample graded in the window (health received x eval_every): the samples offered when
        # the monitor keeps up, fewer when it falls behind
        "monitor_us_per_sample": (cpu1[1] - cpu0[1]) / (len(lat) * eval_every) * 1e6 if lat else None,
        "seconds": seconds,
        "warm_s": warm,
        # when the slow health messages came: {second of the window: how many took >= max_p99_ms}
        "late_by_second": {str(k): v for k, v in sorted(late.items())},  # JSON keys are strings
        "monitor_summary": " | ".join(m.group(0) if m else text[-500:] for m, text in zip(ms, mon_texts)),
        "sim_summary": sm.group(0) if sm else sim_text[-500:],
    }
    out["ok"] = bool(lost == 0 and out["health_missing"] == 0 and out["p99_ms"] is not None
                     and out["p99_ms"] < max_p99_ms)
    return out


def _last_seq(obj: dict) -> int:
    """The seq of a sample payload, or of a frame's last sample."""
    t = obj["t"]
    return obj["seq"] + len(t) - 1 if type(t) is list else obj["seq"]


def bench_live(steps=(100, 200, 500, 1000, 2000, 5000), seconds: float = 10.0, refine: int = 3,
               frame: int | None = None, monitors: int = 1) -> dict:
    """Step up the rig count until a step loses a sample or misses p99 < 50 ms, then bisect
    ``refine`` times between the last passing and the first failing count (to a multiple of
    10; three halvings resolve 1000 passing and 2000 failing to 125 rigs, where two would stop
    at "1250 failed" with 1000 the figure); the figure is the largest
    passing step (``rigs`` None with a ``reason`` if none passes or the monitor node is missing)."""
    try:
        import hydromon.bus.monitor  # noqa: F401
    except ImportError as exc:
        return {"rigs": None, "samples_per_s": None, "lost": None, "p50_ms": None, "p99_ms": None,
                "reason": f"no monitor node: {exc}"}
    results = []

    def run(n):
        what = ("samples" if frame is None else f"frames of {frame}") + (f", {monitors} monitors" if monitors > 1 else "")
        _log(f"live ({what}): {n} rigs for {seconds:g} s (load average {os.getloadavg()[0]:.2f})")
        load = os.getloadavg()[0]
        try:
            r = live_step(n, seconds, frame=frame, monitors=monitors)
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
        return {"rigs": None, "frame": frame, "monitors": monitors, "samples_per_s": None, "lost": None, "p50_ms": None, "p99_ms": None,
                "reason": reason, "steps": results}
    out = {k: best.get(k) for k in ("rigs", "frame", "monitors", "samples_per_s", "lost", "p50_ms", "p99_ms", "cpu_sim",
                                    "cpu_monitor", "cpu_probe", "monitor_us_per_sample", "health_missing",
                                    "seconds", "loadavg_1min")}
    out["limited_by"] = (f"{fail} rigs failed" + (" (error)" if broken else "") if fail is not None
                         else f"largest step tried ({steps[-1]} rigs)")
    out["steps"] = results
    return out
