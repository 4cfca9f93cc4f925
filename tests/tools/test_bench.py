"""hydromon bench: the command's JSON contract, and the naive baseline pinned to the compiled path.

No timing assertions: the figures themselves are measured by ``hydromon bench``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import orjson
import pytest

from hydromon.contract import RigConfig
from hydromon.tools.bench import paper_var_samples
from monitor.ident_options import IdentOptions
from monitor.layout import OFFSETS
from monitor.pipeline import Fleet
from monitor.reference import NaiveIdentifier

KEYS = ("core_single", "core_batch", "replay_direct", "live", "transport_ceiling", "baseline_naive",
        "memory_per_rig")

PROJECT_HISTORY = Path(__file__).resolve().parents[2] / "benchmarks" / "history.jsonl"


def _run_compiled(samples, options=None, config=None):
    fleet = Fleet(options=options)
    fleet.add_rig("rig", config)
    fleet.update(np.zeros(len(samples), np.int64), samples)
    return fleet


@pytest.fixture(scope="module")
def clean_run():
    return paper_var_samples(8.0, noise="none")


def test_naive_agrees_with_compiled_estimates(clean_run):
    fleet = _run_compiled(clean_run)
    naive = NaiveIdentifier()
    for row in clean_run:
        naive.update(row)
    p_naive, _ = naive.estimates()
    p_comp = np.array(list(fleet.estimate(0).params.values()))
    assert np.all(np.isfinite(p_comp))
    np.testing.assert_allclose(p_naive, p_comp, rtol=1e-6, atol=0)


def test_naive_state_matches_compiled_state_row(clean_run):
    fleet = _run_compiled(clean_run[:600])
    naive = NaiveIdentifier()
    for row in clean_run[:600]:
        naive.update(row)
    st, ref = naive.state_row(), fleet.states[0]
    # field by field, relative to the field's size: residuals are differences of O(1) numbers
    # that cancel to ~1e-8, so their last digits are round-off of the same size in both
    for name, (o, n) in OFFSETS.items():
        scale = np.abs(ref[o:o + n]).max()
        np.testing.assert_allclose(st[o:o + n], ref[o:o + n], rtol=1e-6, atol=1e-6 * scale, err_msg=name)


def test_naive_gates_glitches_like_the_compiled_kernel(clean_run):
    rows = clean_run[:600].copy()
    rows[300, 2] += 3e7  # a pressure glitch the outlier gate replaces
    rows[450, 1] += 0.05  # and a position glitch
    rows[520:522, 3] -= 2e7  # and a burst of two on x4
    rows[598:600, 2] += 2e7  # and one at the end, still held by the gate
    fleet = _run_compiled(rows)
    naive = NaiveIdentifier()
    for row in rows:
        naive.update(row)
    st, ref = naive.state_row(), fleet.states[0]
    o, _ = OFFSETS["OUTLIERS"]
    assert ref[o:o + 4].tolist() == [1, 1, 2, 0]  # the held burst is not judged yet
    for name, (o, n) in OFFSETS.items():
        scale = np.abs(ref[o:o + n]).max()
        np.testing.assert_allclose(st[o:o + n], ref[o:o + n], rtol=1e-6, atol=1e-6 * scale, err_msg=name)


def test_naive_follows_options_and_config():
    # a different forgetting factor, filter bandwidths and rig: the two still agree
    opts = IdentOptions(lam=0.999, a_force=30.0, a_chamber=20.0, warmup=0.2)
    cfg = RigConfig(A1=0.006, F_L=2000.0)
    from plant_sim.noise import noise_model
    from plant_sim.profiles import PaperVariable
    from plant_sim.simulate import simulate

    s = simulate(PaperVariable(), 6.0, config=cfg, noise=noise_model("realistic"), seed=3).samples
    fleet = _run_compiled(s, opts, cfg)
    naive = NaiveIdentifier(cfg, opts)
    for row in s:
        naive.update(row)
    np.testing.assert_allclose(naive.estimates()[0], np.array(list(fleet.estimate(0).params.values())),
                               rtol=1e-6)


def test_bench_quick_json(tmp_path):
    hist = tmp_path / "history.jsonl"
    out = subprocess.run([sys.executable, "-m", "hydromon.cli", "bench", "--quick", "--no-live", "--json",
                          "--history", str(hist)], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)  # exactly one JSON document on stdout
    for key in KEYS:
        assert key in doc
    for key in ("core_single", "core_batch", "replay_direct", "transport_ceiling", "baseline_naive",
                "kernel_us_per_sample", "replay_direct_framed"):
        assert isinstance(doc[key], float) and doc[key] > 0, (key, doc[key])
    assert doc["details"]["replay_direct_framed"]["frame"] == 10
    assert doc["memory_per_rig"]["state_bytes"] > 0 and doc["memory_per_rig"]["rss_bytes"] > 0
    assert doc["live"]["rigs"] is None and doc["live"]["reason"]
    lines = hist.read_text().splitlines()
    assert len(lines) == 1
    rec = json.loads(lines[0])
    assert rec["timestamp"] and rec["core_single"] == doc["core_single"]
    for k in ("platform", "cpu_count", "python", "numpy", "numba"):
        assert rec["machine"][k]
    png = tmp_path / "history.png"  # the run just appended, drawn
    from hydromon.cli.main import main

    assert main(["bench", "--history", str(hist), "--plot-history", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_history_plot_draws_each_run_and_its_share_of_the_ceiling(tmp_path, capsys):
    from hydromon.cli.main import main
    from hydromon.tools.bench.history_plot import history_figure, load_history

    runs = load_history(PROJECT_HISTORY)  # the project's own history parses whole
    assert len(runs) >= 20
    runs = [{"timestamp": "t0", "core_single": 2e5, "transport_ceiling": 2e5, "live": {"rigs": 750}},
            {"timestamp": "t1", "core_single": 1e5, "transport_ceiling": 1.5e5, "live": {"rigs": None},
             "details": {"quick": True}},
            {"timestamp": "t2", "core_single": 3e5, "transport_ceiling": 3e5, "live": {"rigs": 1200},
             "kernel_us_per_sample": 1.5, "monitor_us_per_sample": 2.5}]
    ax_t, ax_l, ax_s, ax_u = history_figure(runs).axes
    mon = [ln for ln in ax_u.lines if ln.get_label() == "monitor_us_per_sample"][0]
    assert mon.get_xdata().tolist() == [2] and mon.get_ydata().tolist() == [2.5]
    share = [ln for ln in ax_s.lines if ln.get_label() == "live / ceiling"][0]
    assert share.get_xdata().tolist() == [0, 2] and share.get_ydata().tolist() == [0.375, 0.4]
    quick = [ln for ln in ax_t.lines if ln.get_label() == "core_single (--quick)"][0]
    assert quick.get_xdata().tolist() == [1] and quick.get_markerfacecolor() == "none"
    bad = tmp_path / "h.jsonl"
    bad.write_text(json.dumps(runs[0]) + "\n" + '{"core_single": 1')  # a run killed while appending
    assert main(["bench", "--history", str(bad), "--plot-history", str(tmp_path / "h.png")]) == 2
    assert f"{bad}:2: not a JSON document" in capsys.readouterr().err
    assert not (tmp_path / "h.png").exists()
    assert main(["bench", "--history", str(tmp_path / "none.jsonl"), "--plot-history", str(tmp_path / "h.png")]) == 2
    assert main(["bench", "--history", str(bad), "--plot-history", str(tmp_path / "no" / "h.png")]) == 2


def test_bench_rejects_bad_flags():
    from hydromon.cli.main import main

    assert main(["bench", "--live-seconds", "0", "--history", ""]) == 2
    assert main(["bench", "--live-rigs", "10,x", "--history", ""]) == 2
    assert main(["bench", "--frame", "1001", "--history", ""]) == 2
    assert main(["bench", "--frame", "-1", "--history", ""]) == 2
    assert main(["bench", "--monitors", "0", "--history", ""]) == 2


def test_shards_hold_every_rig_once_and_every_severity():
    from hydromon.tools.bench.live import shard_ids

    assert shard_ids(3, 1) == ["rig-0000", "rig-0001", "rig-0002"]
    ids = shard_ids(10, 3)
    assert ids[:4] == ["m0-rig-0000", "m1-rig-0001", "m2-rig-0002", "m0-rig-0003"]
    assert sorted(i.split("-", 1)[1] for i in ids) == shard_ids(10, 1)


@pytest.mark.network
@pytest.mark.parametrize("frame", [None, 10])
def test_live_step_smoke(frame):
    # sim + monitor processes on loopback: every health message arrives, nothing is lost
    from hydromon.tools.bench import live_step

    # a 0 ms limit makes every health message late: late_by_second is filled, and the step
    # must still serialise as the history file and --json write it (a run once crashed there)
    r = live_step(5, seconds=2.0, warm=1.0, grace=3.0, max_p99_ms=0.0, frame=frame)  # grace: no latency bound here
    assert r["lost"] == 0 and r["frame"] == frame and r["monitor_us_per_sample"] > 0
    assert r["health_expected"] == 5 * 20 and r["health_received"] == r["health_expected"]
    assert r["p50_ms"] > 0 and r["p99_ms"] >= r["p50_ms"]
    assert r["cpu_monitor"] > 0
    assert not r["ok"] and sum(r["late_by_second"].values()) == r["health_received"]
    assert orjson.loads(orjson.dumps(r, option=orjson.OPT_SERIALIZE_NUMPY))["late_by_second"] == r["late_by_second"]


@pytest.mark.network
def test_live_step_with_two_monitors_grades_each_shard_once():
    from hydromon.tools.bench import live_step

    r = live_step(6, seconds=2.0, warm=1.0, grace=3.0, frame=10, monitors=2)
    assert r["monitors"] == 2 and r["lost"] == 0 and r["health_missing"] == 0
    assert r["health_received"] == r["health_expected"] == 6 * 20  # no rig graded twice, none left out
    summaries = r["monitor_summary"].split(" | ")
    assert [s.split(" rig(s)")[0] for s in summaries] == ["3", "3"]


def test_naive_rejects_bad_shape():
    with pytest.raises(ValueError, match="shape"):
        NaiveIdentifier().update([1.0, 2.0, 3.0])


def test_bench_writes_no_history_unless_asked():
    from hydromon.cli.main import build_parser

    assert build_parser().parse_args(["bench"]).history is None


def test_the_frame_codec_measurement_decodes_every_encoding_to_the_frames_values():
    from hydromon.tools.bench.frame_codec import measure

    got = measure(5, passes=1)  # raises if an encoding does not give back the frame's values
    assert set(got) == {"json-msgspec", "json-orjson", "json-base64", "samples"}
    assert got["json-base64"][2] < got["json-msgspec"][2] < got["samples"][2]  # bytes a sample


def test_the_frame_core_measurement_takes_every_sample_both_ways(capsys):
    from hydromon.engine.core import MonitorCore
    from hydromon.store.fleetfile import spread_fleet
    from hydromon.tools.bench.frame_core import main, messages

    spec = spread_fleet(4, noise="realistic")
    for frame in (7, None):
        core = MonitorCore()
        core.process(messages(spec, 0.5, frame))
        assert core.counters.accepted == 4 * 50 and core.counters.rejected_total == 0
    assert main(["20", "10", "1"]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 2
