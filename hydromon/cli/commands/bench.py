"""``hydromon bench``: the performance figures (a table, or one JSON document with --json)."""

from __future__ import annotations

import sys
from pathlib import Path

NAME = "bench"
HELP = "measure the performance figures (core, batch, replay, naive baseline, memory, transport, live)"
KERNELS = True  # compiled numerical kernels: a cold cache compiles them first (hydromon.cli.main)
EXAMPLES = (
    'hydromon bench --quick',
    'hydromon bench --json --live-seconds 60',
    'hydromon bench --json --no-live-samples --monitors 2 --live-rigs 1000,2000',
)

def add_arguments(parser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON document on stdout")
    parser.add_argument("--quick", action="store_true",
                        help="small sizes (CI, tests; live: one step of the first rig count, <= 3 s); rougher numbers")
    parser.add_argument("--no-live", action="store_true", help="skip the live sim + monitor step-up")
    parser.add_argument("--live-seconds", type=float, default=10.0, metavar="S",
                        help="window per rig count of the live step-up [s] (default 10; docs/performance.md: 60)")
    parser.add_argument("--live-rigs", default=None, metavar="N,N,...",
                        help="rig counts of the live step-up (default 100,200,500,1000,2000,5000)")
    parser.add_argument("--frame", type=int, default=10, metavar="N",
                        help="samples a frame in the live step-up (sim --frame N) and in replay_direct_framed "
                             "(default 10; 0: one message per sample only)")
    parser.add_argument("--monitors", type=int, default=1, metavar="K",
                        help="monitor processes in the live step-up, each grading its shard of the rigs "
                             "(--rigs m<k>-*) from the one sim (default 1)")
    parser.add_argument("--no-live-samples", action="store_true",
                        help="skip the second live step-up with one message per sample (live_samples)")
    parser.add_argument("--history", default=None, metavar="FILE",
                        help="append the run to this JSON-lines file (default: none; the project's own run "
                             "history is benchmarks/history.jsonl in its repository)")
    parser.add_argument("--plot-history", default=None, metavar="PNG",
                        help="measure nothing: draw the --history file's runs into PNG (throughput, live rigs "
                             "and their share of the transport ceiling, each against its target)")


def _fmt(v, unit: str = "") -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        if abs(v) >= 100:
            return f"{v:,.0f}{unit}"
        return f"{v:.3g}{unit}"
    return f"{v}{unit}"


def print_table(res, stream=None) -> None:
    """The run as a rich table (on stdout unless ``stream``)."""
    from rich.console import Console
    from rich.table import Table

    d = res.details
    t = Table(title="hydromon bench", show_lines=False)
    t.add_column("figure")
    t.add_column("value", justify="right")
    t.add_column("unit")
    t.add_column("notes")
    cs = d.get("core_single", {})
    t.add_row("core_single", _fmt(res.core_single), "samples/s",
              f"1 rig, batch 1 (live path); batch 100: {_fmt(cs.get('batch_100'))}/s")
    t.add_row("core_batch", _fmt(res.core_batch), "samples/s",
              f"{d.get('core_batch', {}).get('rigs')} rigs, one sample each per update, {d.get('core_batch', {}).get('threads')} threads")
    t.add_row("kernel_us_per_sample", _fmt(res.kernel_us_per_sample), "us",
              "the compiled pipeline alone, one thread (core_batch's one-thread figure)")
    rd = d.get("replay_direct", {})
    t.add_row("replay_direct", _fmt(res.replay_direct), "samples/s",
              f"in-memory MCAP, {rd.get('rigs')} rigs, via {rd.get('via')}; "
              f"pydantic+Fleet.update: {_fmt(rd.get('pydantic'))}/s")
    t.add_row("baseline_naive", _fmt(res.baseline_naive), "samples/s",
              f"numpy per sample; core_single is {res.speedup_vs_naive:.1f}x, compiled "
              f"identification alone {d.get('identify_single', {}).get('speedup_vs_naive', float('nan')):.1f}x")
    if res.replay_direct_framed is not None:
        t.add_row("replay_direct_framed", _fmt(res.replay_direct_framed), "samples/s",
                  f"the same recording as frames of {d.get('replay_direct_framed', {}).get('frame')}")
    if res.replay_direct_framed_jobs is not None:
        t.add_row("replay_direct_framed_jobs", _fmt(res.replay_direct_framed_jobs), "samples/s",
                  f"the same in {d.get('replay_direct_framed', {}).get('jobs')} processes (replay --direct --jobs)")
    m = res.memory_per_rig
    t.add_row("memory_per_rig", _fmt(m["state_bytes"]), "bytes",
              f"state arrays; RSS growth {_fmt(m['rss_bytes'])} B/rig over {m['rigs']} rigs")
    tr = d.get("transport_ceiling", {})
    t.add_row("transport_ceiling", _fmt(res.transport_ceiling), "messages/s",
              f"hydromon sim --rate 0 -> bare zenoh sub, loopback tcp; cpu sub {_fmt(tr.get('subscriber_cpu'))}, "
              f"pub {_fmt(tr.get('publisher_cpu'))} cores; raw zenoh pub loop "
              f"{_fmt(tr.get('raw', {}).get('messages_per_s'))}/s")
    for name, live in (("live", res.live or {}), ("live_samples", res.live_samples)):
        if live is None:
            continue
        framed = f"frames of {live['frame']}, " if live.get("frame") else "one message a sample, "
        if (live.get("monitors") or 1) > 1:
            framed += f"{live['monitors']} monitors, "
        if live.get("rigs"):
            t.add_row(name, _fmt(live.get("samples_per_s")), "samples/s",
                      f"{framed}{live['rigs']} rigs, lost {live.get('lost')}, p50 {_fmt(live.get('p50_ms'))} ms, "
                      f"p99 {_fmt(live.get('p99_ms'))} ms")
        else:
            t.add_row(name, "-", "", str(live.get("reason", "not measured")))
    t.add_row("monitor_us_per_sample", _fmt(res.monitor_us_per_sample), "us",
              "live's monitor CPU (all threads, all monitors) per sample, its best step")
    console = Console(file=stream or sys.stdout)
    console.print(t)
    mi = res.machine
    console.print(f"{mi.get('platform')}, {mi.get('cpu_count')} cpus ({mi.get('cpu', '?')}), python "
                  f"{mi.get('python')}, numpy {mi.get('numpy')}, numba {mi.get('numba')}")
    for name, live in (("live", res.live or {}), ("live_samples", res.live_samples or {})):
        steps = live.get("steps") or []
        if not steps:
            continue
        st = Table(title=f"{name} step-up (sim --rate 1 + monitor, loopback)")
        for col in ("rigs", "ok", "lost", "health missing", "p50 ms", "p99 ms", "cpu sim", "cpu monitor",
                    "monitor us/sample", "load"):
            st.add_column(col, justify="right")
        for r in steps:
            if "error" in r:
                st.add_row(str(r["rigs"]), "error", "", "", "", "", "", "", "", _fmt(r.get("loadavg_1min")))
                continue
            st.add_row(str(r["rigs"]), "yes" if r.get("ok") else "no", _fmt(r.get("lost")),
                       _fmt(r.get("health_missing")), _fmt(r.get("p50_ms")), _fmt(r.get("p99_ms")),
                       _fmt(r.get("cpu_sim")), _fmt(r.get("cpu_monitor")), _fmt(r.get("monitor_us_per_sample")),
                       _fmt(r.get("loadavg_1min")))
        console.print(st)
        for r in steps:
            if "error" in r:
                console.print(f"{name} {r['rigs']} rigs: error: {r['error']}")


def run(args) -> int:
    import orjson

    from hydromon.tools.bench import BenchOptions, append_history, run_bench, to_json
    from hydromon.cli.checks import writable_file

    if args.plot_history is not None:
        from hydromon.tools.bench.history_plot import history_figure, load_history
        from hydromon.cli.checks import replace_on_success

        if not args.history:
            raise ValueError("--plot-history needs a --history file to draw")
        if not Path(args.history).is_file():
            raise ValueError(f"--history {args.history!r}: no such file")
        writable_file("--plot-history", args.plot_history)
        runs = load_history(args.history)
        fig = history_figure(runs)
        with replace_on_success(args.plot_history, "wb") as f:
            fig.savefig(f, dpi=110, format="png")
        print(f"hydromon bench: {len(runs)} runs of {args.history} drawn into {args.plot_history}", file=sys.stderr)
        return 0
    if not args.live_seconds > 0:
        raise ValueError(f"--live-seconds {args.live_seconds!r} must be > 0")
    if not 0 <= args.frame <= 1000:
        raise ValueError(f"--frame {args.frame!r} must be 0..1000 samples")
    if not 1 <= args.monitors <= 64:
        raise ValueError(f"--monitors {args.monitors!r} must be 1..64")
    kw = {}
    if args.live_rigs:
        try:
            steps = tuple(int(x) for x in args.live_rigs.split(",") if x.strip())
        except ValueError:
            raise ValueError(f"--live-rigs {args.live_rigs!r}: expected N,N,...") from None
        if not steps or min(steps) < 1:
            raise ValueError(f"--live-rigs {args.live_rigs!r}: rig counts must be >= 1")
        kw["live_steps"] = steps
    opts = BenchOptions(quick=args.quick, live=not args.no_live, live_seconds=args.live_seconds,
                        frame=args.frame or None, live_samples=not args.no_live_samples, monitors=args.monitors,
                        **kw)
    res = run_bench(opts)
    if args.history:
        path = Path(args.history)
        path.parent.mkdir(parents=True, exist_ok=True)
        append_history(res, path)
    if args.json:
        sys.stdout.write(orjson.dumps(to_json(res), option=orjson.OPT_SERIALIZE_NUMPY).decode() + "\n")
    else:
        print_table(res)
    return 0
