"""``hydromon demo`` opens the whole picture: it prints the dashboard's URL beside its table, and
the fleet page works (every rig at its true grade, no JavaScript error) while the demo runs."""

from __future__ import annotations

import re
import signal

import pytest

from helpers import wait_for
from hydromon.store.fleetfile import default_fleet, true_grade
from webhelpers import Procs, Watched, chromium, fleet_grades

URL = re.compile(r"dashboard: (http://127\.0\.0\.1:\d+/)")


@pytest.mark.network
@pytest.mark.timeout(240)
def test_demo_prints_the_dashboard_url_and_the_page_works_while_it_runs(tmp_path):
    truth = {r.id: true_grade(r) for r in default_fleet().rigs}
    procs = Procs(tmp_path)
    try:
        procs.start("demo", "demo", "--duration", "120", "--plain", "--out", str(tmp_path))
        wait_for(lambda: URL.search(procs.log("demo")), 180, "the dashboard's URL", alive=procs.check_alive)
        url = URL.search(procs.log("demo")).group(1)
        with chromium() as ctx:
            fleet = Watched(ctx)
            fleet.page.goto(url)
            wait_for(lambda: fleet_grades(fleet.page) == truth, 60, f"the fleet page at {truth}",
                     alive=procs.check_alive, poll_s=0.2)
            rig = Watched(ctx)
            rig.page.goto(url + "rig/table4-g3")
            rig.page.wait_for_selector("#graded .plot canvas", timeout=15_000)
            # the demo's monitor grades on the default ranges: the rig page draws their bands
            note = rig.page.evaluate("() => document.querySelector('#rangesnote').textContent")
            assert "dashboard's --ranges" in note or "monitor grades it" in note, note
            for w in (fleet, rig):
                assert w.errors == [], w.errors
        # the table printed on stdout has the URL above it
        assert re.search(r"dashboard: http://127\.0\.0\.1:\d+/\nrig ", procs.log("demo")), procs.log("demo")[-2000:]
        assert procs.stop("demo", signal.SIGINT, timeout_s=60) == 0, procs.log("demo")[-3000:]
        assert "5/5 rigs at their true grade" in procs.log("demo")
    finally:
        procs.close()
