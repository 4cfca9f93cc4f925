"""``hydromon dashboard --recording FILE``: a recording in the same pages, served by the real
command (the golden recording of the paper's five Table 4 rigs, realistic noise)."""

from __future__ import annotations

import json
import urllib.request
from pathlib import Path

import orjson
import pytest

from hydromon.store.mcap_read import read_recording
from webhelpers import Procs, Watched, chromium, fleet_grades

GOLDEN = Path(__file__).resolve().parents[2] / "recordings" / "table4-realistic.mcap"


@pytest.mark.timeout(120)
def test_a_recording_in_the_pages(tmp_path):
    last = {}
    n_health = {}
    for key, payload, _, _ in read_recording(GOLDEN):
        if key.endswith("/health"):
            rig = key.split("/")[2]
            last[rig] = orjson.loads(payload)["grade"]
            n_health[rig] = n_health.get(rig, 0) + 1
    procs = Procs(tmp_path)
    try:
        url = procs.dashboard("dashboard", "--recording", str(GOLDEN))
        with urllib.request.urlopen(url + "api/fleet", timeout=10) as r:
            fleet = json.loads(r.read())
        assert {row["rig"]: row["grade"] for row in fleet["rows"]} == last
        assert fleet["live"] is False and all(row["flag"] is None for row in fleet["rows"])
        with urllib.request.urlopen(url + "api/rig/table4-g3", timeout=10) as r:
            rig = json.loads(r.read())
        # about 900 points per rig over the recording however fast it was made (this one: in 0.5 s)
        assert len(rig["points"]["wall"]) >= n_health["table4-g3"] // 2
        with chromium() as ctx:
            page = Watched(ctx)
            page.page.goto(url)
            page.page.wait_for_function("() => document.querySelectorAll('#fleet tbody tr').length === 5")
            assert fleet_grades(page.page) == last
            assert "recording" in page.page.evaluate("() => document.querySelector('#source').textContent")
            assert page.errors == []
    finally:
        procs.close()


def _rewritten(path, keep, tail_s: float = 0.0):
    """The golden recording's messages that ``keep(key)`` takes, into ``path``, and then each
    rig's last sample again every second for ``tail_s`` seconds [s] (the rigs ran on)."""
    from hydromon.store.mcap_write import RecordingWriter

    last_ns, last_sample = 0, {}
    with open(path, "wb") as f:
        w = RecordingWriter(f)
        for key, payload, log_ns, pub_ns in read_recording(GOLDEN):
            last_ns = max(last_ns, log_ns)
            if key.endswith("/sample"):
                last_sample[key] = payload
            if keep(key):
                w.write(key, payload, log_ns, pub_ns)
        for k in range(1, int(tail_s) + 1):
            for key, payload in last_sample.items():
                w.write(key, payload, last_ns + k * 1_000_000_000, last_ns + k * 1_000_000_000)
        w.close()
    return last_ns / 1e9


@pytest.mark.timeout(120)
def test_a_recording_s_ages_are_taken_at_its_end_and_one_without_verdicts_says_so(tmp_path):
    procs = Procs(tmp_path)
    try:
        # the monitor stopped 60 s before the recorder: every verdict is a minute old at the end
        last = _rewritten(tmp_path / "monitor-died.mcap", lambda key: True, tail_s=60)
        url = procs.dashboard("died", "--recording", str(tmp_path / "monitor-died.mcap"))
        with urllib.request.urlopen(url + "api/fleet", timeout=10) as r:
            fleet = json.loads(r.read())
        with urllib.request.urlopen(url + "api/info", timeout=10) as r:
            info = json.loads(r.read())
        assert info["end"] == pytest.approx(last + 60.0) and info["verdicts"] > 0, info
        ages = [fleet["now"] - row["arrived"] for row in fleet["rows"]]
        assert len(ages) == 5 and all(59.0 < a < 62.0 for a in ages), ages

        _rewritten(tmp_path / "samples-only.mcap", lambda key: key.endswith("/sample") or key.endswith("/config"))
        url = procs.dashboard("bare", "--recording", str(tmp_path / "samples-only.mcap"))
        assert "holds no health verdicts" in procs.log("bare") and "hydromon evaluate" in procs.log("bare")
        with chromium() as ctx:
            page = Watched(ctx)
            page.page.goto(url)
            page.page.wait_for_function("() => document.querySelector('#source').textContent.includes('no health')")
            assert page.errors == []
    finally:
        procs.close()


@pytest.mark.timeout(120)
def test_a_rig_with_one_verdict_is_plotted_over_a_minute_with_24_hour_ticks(tmp_path):
    """uPlot spans one time value over years, and labels it in the browser's locale (US dates in
    an en-US browser): the rig page gives one verdict a minute around it and 24-hour labels."""
    first = set()

    def keep(key):  # every rig's samples and config, and its first verdict only
        if key.endswith("/health"):
            if key in first:
                return False
            first.add(key)
        return True

    _rewritten(tmp_path / "one-verdict.mcap", keep)
    procs = Procs(tmp_path)
    try:
        url = procs.dashboard("one", "--recording", str(tmp_path / "one-verdict.mcap"))
        with chromium() as ctx:
            page = Watched(ctx)
            page.page.goto(url + "rig/table4-g3")
            page.page.wait_for_selector("#graded .plot canvas", timeout=15_000)
            span = page.page.evaluate("() => [...plots.values()].map(u => u.scales.x.max - u.scales.x.min)")
            assert span and all(s == pytest.approx(60.0) for s in span), span
            labels = page.page.evaluate("() => timeTicks(null, [1e9, 1e9 + 15], 0, 0, 15)")
            assert all(len(x) == 8 and x[2] == ":" and x[5] == ":" for x in labels), labels
            assert page.errors == []
    finally:
        procs.close()
