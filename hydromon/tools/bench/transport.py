"""``transport_ceiling`` of ``hydromon bench``: a bare zenoh subscriber fed as fast as possible."""

from __future__ import annotations

import multiprocessing as mp
import subprocess
import sys
import time

import orjson

from .procs import _cpu_seconds, _stop


def _transport_sub(seconds: float, ready, out) -> None:
    import zenoh

    from hydromon.bus.session import listening_session

    # on a free port (another if it was taken before the bind); the parent learns it from `ready`
    with listening_session("peer") as (session, endpoint):
        sub = session.declare_subscriber("hydro/rig/*/sample", zenoh.handlers.FifoChannel(65536))
        ready.put(endpoint)
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
    import zenoh

    from hydromon.bus.session import JSON, open_session

    with open_session("peer", connect=[endpoint]) as session:
        pubs = [session.declare_publisher(f"hydro/rig/rig-{i:04d}/sample", encoding=JSON,
                                          congestion_control=zenoh.CongestionControl.BLOCK)
                for i in range(n_keys)]
        # the subscriber's interest must have arrived, or the first puts go nowhere and its
        # window outlasts ours (a fixed 1 s sleep assumed it always does)
        deadline = time.monotonic() + 30.0
        while not (pubs[0].matching_status.matching and pubs[-1].matching_status.matching):
            if time.monotonic() > deadline:
                raise RuntimeError("no subscriber matched the transport publisher in 30 s")
            time.sleep(0.01)
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
    ctx = mp.get_context("spawn")

    def measure(start_pub):
        ready, out_sub = ctx.Queue(), ctx.Queue()
        sub = ctx.Process(target=_transport_sub, args=(seconds, ready, out_sub), daemon=True)
        sub.start()
        try:
            endpoint = ready.get(timeout=60)
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
