"""The dashboard under a large fleet: N rigs' health at 10 Hz each into ``hydromon dashboard``.

This process listens on a loopback zenoh endpoint and publishes contract-valid health for N rigs
(each ten times a second, values drifting, grades spread over the five levels, one monitor's
liveliness token); ``hydromon dashboard`` runs as a separate process connected to it, with the
fleet page open in headless Chromium. It prints the dashboard process's CPU use (utime + stime
from /proc over the measured window, in cores), its resident memory, what the publisher achieved,
and the fleet page's responsiveness (the longest delay of a 50 ms timer in the page over 5 s, and
how long the page takes to show the result of typing a filter).

    python benchmarks/dashboard_load.py --rigs 1000 --seconds 30
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request

import orjson

from hydromon.bus.session import listening_session
from hydromon.contract import GRADES, PARAM_NAMES

CLI = [sys.executable, "-m", "hydromon.cli"]
URL = re.compile(r"hydromon dashboard: (http://127\.0\.0\.1:\d+/)")


def cpu_seconds(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def publish(session, rigs: int, rate: float, stop: threading.Event, sent: list) -> None:
    """Health of ``rigs`` rigs at ``rate`` Hz each, spread evenly over each period."""
    ids = [f"rig-{i:04d}" for i in range(rigs)]
    keys = [session.declare_keyexpr(f"hydro/rig/{r}/health") for r in ids]
    period = 1.0 / rate
    seq, t0 = 0, time.monotonic()
    while not stop.is_set():
        for i, key in enumerate(keys):
            level = i % 5
            drift = 1.0 + 0.01 * ((seq + i) % 7)
            h = {"seq": seq * 10 + 9, "t": seq * period, "grade": GRADES[level], "level": level,
                 "confidence": 0.6 + 0.05 * (seq % 5), "status": "ok", "node": "bench", "epoch": 1, "ranges": "default",
                 "params": {p: (1.0 + 0.1 * j) * drift for j, p in enumerate(PARAM_NAMES)},
                 "param_grades": {"K_sv": GRADES[level], "f_c": "health", "B_fv": "health", "C_ip": "health",
                                  "C_ep": "health"},
                 "std_errors": {p: 0.01 for p in PARAM_NAMES}}
            session.put(key, orjson.dumps(h))
            sent[0] += 1
        seq += 1
        wait = t0 + seq * period - time.monotonic()
        if wait > 0:
            stop.wait(wait)


def page_figures(url: str, seconds: float) -> dict:
    from playwright.sync_api import sync_playwright

    args = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
            "--disable-component-update", "--disable-sync", "--no-first-run"]
    with tempfile.TemporaryDirectory() as profile, sync_playwright() as pw:
        ctx = pw.chromium.launch_persistent_context(profile, executable_path="/usr/bin/chromium", args=args,
                                                    viewport={"width": 1400, "height": 1000})
        page = ctx.new_page()
        errors = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(url)
        page.wait_for_function("() => document.querySelectorAll('#fleet tbody tr').length >= 500", timeout=60_000)
        lag = page.evaluate("""(ms) => new Promise(done => {
            let last = performance.now(), worst = 0;
            const id = setInterval(() => { const now = performance.now(); worst = Math.max(worst, now - last - 50);
                                           last = now; }, 50);
            setTimeout(() => { clearInterval(id); done(worst); }, ms);
        })""", seconds * 1000)
        t = time.monotonic()
        page.fill("#filter", "rig-0042")
        page.wait_for_function("() => document.querySelectorAll('#fleet tbody tr').length === 1", timeout=10_000)
        filter_s = time.monotonic() - t
        counts = page.evaluate("() => document.querySelector('#counts').textContent")
        ctx.close()
    return {"timer_lag_max_ms": round(lag, 1), "filter_s": round(filter_s, 3), "counts": counts, "errors": errors}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rigs", type=int, default=1000)
    ap.add_argument("--rate", type=float, default=10.0, help="health per rig per second (default 10)")
    ap.add_argument("--seconds", type=float, default=30.0, help="measured window [s] (default 30)")
    ap.add_argument("--warmup", type=float, default=10.0, help="seconds before measuring (default 10)")
    args = ap.parse_args()
    with listening_session("peer") as (session, ep), tempfile.TemporaryDirectory() as tmp:
        token = session.liveliness().declare_token("hydro/monitor/bench")
        log = open(os.path.join(tmp, "dashboard.log"), "wb")
        proc = subprocess.Popen(CLI + ["dashboard", "--port", "0", "--state-dir", tmp, "--connect", ep],
                                stdout=log, stderr=subprocess.STDOUT, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        stop, sent = threading.Event(), [0]
        pub = threading.Thread(target=publish, args=(session, args.rigs, args.rate, stop, sent), daemon=True)
        try:
            deadline = time.monotonic() + 60
            while not URL.search(open(log.name).read()):
                if time.monotonic() > deadline or proc.poll() is not None:
                    raise SystemExit(open(log.name).read())
                time.sleep(0.1)
            url = URL.search(open(log.name).read()).group(1)
            pub.start()
            time.sleep(args.warmup)
            c0, s0, t0 = cpu_seconds(proc.pid), sent[0], time.monotonic()
            page = {}
            page_thread = threading.Thread(target=lambda: page.update(page_figures(url, 5.0)))
            page_thread.start()
            time.sleep(args.seconds)
            c1, s1, t1 = cpu_seconds(proc.pid), sent[0], time.monotonic()
            page_thread.join(120)
            with urllib.request.urlopen(url + "api/fleet", timeout=10) as r:
                fleet = json.loads(r.read())
            out = {"rigs": args.rigs, "rate_hz": args.rate, "window_s": round(t1 - t0, 1),
                   "published_per_s": round((s1 - s0) / (t1 - t0)), "dashboard_cores": round((c1 - c0) / (t1 - t0), 3),
                   "dashboard_rss_mb": round(rss_mb(proc.pid)),
                   "rigs_on_dashboard": fleet.get("counts", {}).get("rigs"),
                   **page}
            print(json.dumps(out))
        finally:
            stop.set()
            pub.join(10)
            proc.terminate()
            proc.wait(20)
            token.undeclare()


if __name__ == "__main__":
    main()
