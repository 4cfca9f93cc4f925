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
