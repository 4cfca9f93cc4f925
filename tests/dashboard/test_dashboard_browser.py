"""The dashboard in a real browser against a loopback system of separate processes.

``hydromon router``; ``hydromon monitor``; ``hydromon dashboard``; ``hydromon sim`` with the
paper's five Table 4 rigs (one per grade); and a second ``hydromon sim`` with one rig,
``press-7``, healthy, then restarted as a faulty rig (its grade changes while the pages are
open). Headless Chromium (Playwright) checks: the fleet page shows every rig at its true grade;
press-7's change reaches the open page without a reload and the events page lists it (and
takes an acknowledgement with a comment, kept in the event log); a rig
page draws its parameter plots (pixels of a screenshot); killing the monitor flags its rigs
``no monitor`` within 2 s; no page logs a JavaScript error; stopping the dashboard greys the open
pages, which say since when and keep their ages counting; a dashboard restarted on the same
state directory shows the acknowledgement.

The grade event on the events page is the monitor's own (``<ns>/rig/<id>/event``), heard on the
bus by this test too.
"""

from __future__ import annotations

import json
import signal
import time

import orjson
import pytest
import zenoh

from helpers import wait_for
from hydromon.bus.session import open_session
from hydromon.contract import Event
from hydromon.store.fleetfile import default_fleet, true_grade
from webhelpers import Procs, Watched, chromium, fleet_flags, fleet_grades, ink

CHANGING = "press-7"


def _warm_kernels() -> None:
    """Compile (or load) the plant and monitor kernels here, so the node processes load a warm cache."""
    from hydromon.engine.core import MonitorCore
    from hydromon.store.fleetfile import FleetSpec, RigSpec
    from hydromon.store.simfiles import iter_blocks

    fleet = FleetSpec(rigs=[RigSpec(id="warm", table4=1)]).build()
    msgs = [("hydro/rig/warm/sample", orjson.dumps(dict(zip(("seq", "t", "ug", "x1", "x3", "x4", "x5"), (s, t, *row)))))
            for blk in iter_blocks(fleet, 100) for s, t, row in zip(blk.seq.tolist(), blk.t.tolist(),
                                                                    blk.samples[0].tolist())]
    assert len(MonitorCore().process(msgs)) == 10


def _fleet_file(path, table4: int):
    path.write_text(json.dumps({"rigs": [{"id": CHANGING, "table4": table4}]}))
    return str(path)


class Events:
    """press-7's events as the monitor publishes them."""

    def __init__(self, session):
        self.got: list[dict] = []
        self.sub = session.declare_subscriber(f"hydro/rig/{CHANGING}/event", zenoh.handlers.FifoChannel(1000))

    def poll(self) -> list[dict]:
        while (m := self.sub.try_recv()) is not None:
            self.got.append(Event.model_validate_json(m.payload.to_bytes()).model_dump(by_alias=True))
        return self.got

    def to_fault(self) -> list[dict]:
        return [e for e in self.poll() if e["kind"] == "grade" and e["to"] == "fault"]


@pytest.mark.network
@pytest.mark.timeout(300)
def test_pages_in_a_browser_against_router_sim_monitor_dashboard_processes(tmp_path):
    _warm_kernels()
    truth = {r.id: true_grade(r) for r in default_fleet().rigs}
    procs = Procs(tmp_path)
    try:
        ep = procs.start_listening("router", "router", ready="listening on")
        bus = ["--mode", "client", "--connect", ep]
        procs.start("monitor", "monitor", "--node", "mon1", *bus)
        url = procs.dashboard("dashboard", "--state-dir", str(tmp_path / "state"), *bus)
        with open_session("client", connect=[ep]) as s:
            wait_for(lambda: any(r.ok is not None for r in s.liveliness().get("hydro/monitor/mon1", timeout=1.0)),
                     120, "the monitor's liveliness token", alive=procs.check_alive)
            heard = Events(s)
            procs.start("sim", "sim", *bus)
            procs.start("sim7", "sim", "--fleet", _fleet_file(tmp_path / "healthy.json", 2), *bus)
            with chromium() as ctx:
                fleet = Watched(ctx)
                fleet.page.goto(url)
                fleet.page.evaluate("() => { window.__notReloaded = true; }")
                want = {**truth, CHANGING: "health"}
                wait_for(lambda: fleet_grades(fleet.page) == want, 90, f"the fleet page to show {want}",
                         alive=procs.check_alive, poll_s=0.2)

                # press-7 degrades: its sim restarts as the paper's faulty rig; the open page follows
                procs.stop("sim7")
                procs.start("sim7b", "sim", "--fleet", _fleet_file(tmp_path / "faulty.json", 3), *bus)

                wait_for(lambda: fleet_grades(fleet.page).get(CHANGING) == "fault", 90, "press-7 at fault on the open fleet page", alive=procs.check_alive, poll_s=0.2)
                assert fleet.page.evaluate("() => window.__notReloaded === true")
                wait_for(heard.to_fault, 10, "the monitor's grade event for press-7")
                reason = heard.to_fault()[0]["reason"]

                events = Watched(ctx)
                events.page.goto(url + "events")
                wait_for(lambda: events.page.evaluate(
                    """() => [...document.querySelectorAll('#events tbody tr')].some(tr =>
                        tr.dataset.kind === 'grade' && tr.textContent.includes('press-7') &&
                        tr.textContent.includes('fault'))"""), 15, "press-7's grade event on the events page")
                row = events.page.locator("#events tbody tr[data-kind=grade]", has_text="press-7").first
                assert reason and reason in row.text_content(), (reason, row.text_content())
                # acknowledged on the page, with a comment: kept in the dashboard's event log
                row.get_by_role("button", name="acknowledge").click()
                row.locator("input[name=comment]").fill("valve swapped <b>today</b>")
                row.locator("input[name=by]").fill("anna")
                row.get_by_role("button", name="save").click()
                wait_for(lambda: "valve swapped <b>today</b>" in row.text_content(), 5, "the acknowledgement shown")
                log = (tmp_path / "state" / "dashboard-events-hydro.jsonl").read_text().splitlines()
                acks = [orjson.loads(x) for x in log if '"ack"' in x]
                assert [(a["comment"], a["by"]) for a in acks] == [("valve swapped <b>today</b>", "anna")]

                rig = Watched(ctx)
                rig.page.goto(url + "rig/table4-g3")
                rig.page.wait_for_selector("#graded .plot canvas", timeout=15_000)
                time.sleep(1.5)  # a few pushes: points beyond the snapshot
                n_plots = rig.page.evaluate("() => document.querySelectorAll('.plot canvas').length")
                assert n_plots == 12, n_plots
                shot = rig.page.locator("#graded .plot").first.screenshot()
                other, colours = ink(shot)
                assert other > 5000 and colours > 20, (other, colours)
                timeline = ink(rig.page.locator("#timeline").screenshot())
                assert timeline[0] > 2000, timeline
                assert rig.page.evaluate("() => document.querySelector('#rig').textContent") == "table4-g3"

                # the monitor dies: its rigs are flagged within 2 s
                assert not any(fleet_flags(fleet.page).values()), fleet_flags(fleet.page)
                procs.stop("monitor", signal.SIGKILL, timeout_s=10)
                killed = time.monotonic()
                wait_for(lambda: all(f in ("no monitor", "silent") for f in fleet_flags(fleet.page).values()), 5,
                         "every rig flagged after the monitor was killed", poll_s=0.05)
                took = time.monotonic() - killed
                assert took < 2.0, f"flagged after {took:.2f} s"
                flags = fleet_flags(fleet.page)
                assert set(flags) == set(want)

                for w in (fleet, events, rig):
                    assert w.errors == [], w.errors
                    assert w.dialogs == []

                # the dashboard server goes: the open pages say since when, grey what they show (the
                # grades as they were then, not live), and their ages keep counting
                procs.stop("dashboard")
                for w in (fleet, rig):
                    wait_for(lambda w=w: w.page.evaluate("() => document.body.classList.contains('offline')"), 10,
                             "the page marked offline")
                    conn = w.page.evaluate("() => document.querySelector('#conn').textContent")
                    assert conn.startswith("disconnected from the dashboard server since "), conn
                ages = """() => [document.querySelector('#fleet tbody tr').children[6].textContent]"""
                said = (fleet.page.evaluate(ages), rig.page.evaluate("() => document.querySelector('#since').textContent"))
                time.sleep(2.5)
                now = (fleet.page.evaluate(ages), rig.page.evaluate("() => document.querySelector('#since').textContent"))
                assert now[0] != said[0] and now[1] != said[1], (said, now)

                # a restarted dashboard shows the acknowledged event, comment and all, from its log
                url2 = procs.dashboard("dashboard2", "--state-dir", str(tmp_path / "state"), *bus)
                again = Watched(ctx)
                again.page.goto(url2 + "events")
                wait_for(lambda: again.page.evaluate(
                    """() => [...document.querySelectorAll('#events tbody tr[data-kind=grade]')].some(tr =>
                        tr.textContent.includes('press-7') && tr.textContent.includes('valve swapped <b>today</b>')
                        && tr.textContent.includes('anna'))"""), 15, "the acknowledgement after a restart")
                assert again.errors == [] and again.dialogs == [], again.errors
    finally:
        procs.close()
    for name in ("dashboard", "dashboard2"):
        assert "Traceback" not in procs.log(name), procs.log(name)
