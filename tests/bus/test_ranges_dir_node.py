"""A live monitor with ``--ranges-dir``: a rig of another size is not graded until its own ranges
file appears, then graded on it; a bad file put over it is refused in one log line and the rig
keeps the ranges it had."""

from __future__ import annotations

import logging
import threading
from contextlib import contextmanager

import orjson
import pytest
import zenoh

from helpers import wait_for
from hydromon.bus.monitor import run_monitor
from hydromon.bus.session import listening_session, open_session
from hydromon.bus.sim import run_sim
from hydromon.contract import RigConfig
from hydromon.store.fleetfile import FleetSpec, RigSpec
from hydromon.store.ranges_dir import RangesDir
from monitor.commission import commission
from plant_sim.noise import noise_model
from plant_sim.params import PlantParams
from plant_sim.profiles import PaperVariable
from plant_sim.simulate import simulate

CONFIG = {"A1": 0.012, "A2": 0.006, "p_s": 16e6}
BASE = {"m": 300.0, "B": 12000.0, "K_sv": 1.4e-4, "f_c": 12.0}


@pytest.fixture(scope="module")
def own_ranges():
    """The rig's ranges from a healthy record of it (the bands relative to its baseline; no twin)."""
    cfg = RigConfig(**CONFIG)
    rec = simulate(PaperVariable(), 30.0, params=PlantParams(**BASE), config=cfg,
                   noise=noise_model("realistic", cfg), seed=3)
    return commission(rec.samples, cfg, runs=0, made_on="test", created="2026-01-01T00:00:00Z").ranges


@contextmanager
def live_rig(tmp_path, spec: FleetSpec, rate: float, **monitor_kw):
    """A monitor node with ``--ranges-dir tmp_path`` (scanned every 0.2 s) and the sim of ``spec``
    at ``rate`` x real time on loopback; yields ``latest()`` (the rig's latest health, draining
    what arrived into ``seen``) and ``seen``. Both stop at the end."""
    rig = spec.ids[0]
    seen: list[dict] = []
    with listening_session() as (mon_s, ep), open_session("peer", connect=[ep]) as sim_s, \
            open_session("peer", connect=[ep]) as obs_s:
        sub = obs_s.declare_subscriber(f"hydro/rig/{rig}/health", zenoh.handlers.FifoChannel(100_000))

        def latest():
            while (m := sub.try_recv()) is not None:
                seen.append(orjson.loads(m.payload.to_bytes()))
            return seen[-1] if seen else None

        stop = threading.Event()
        mon = threading.Thread(target=run_monitor, args=(mon_s,), daemon=True, kwargs={
            "stop_event": stop, "node_name": "m", "stale_after_s": None, "ranges_dir": RangesDir(tmp_path),
            "ranges_scan_s": 0.2, **monitor_kw})
        mon.start()
        sim = threading.Thread(target=run_sim, args=(sim_s, spec), kwargs={"rate": rate, "stop_event": stop},
                               daemon=True)
        try:
            wait_for(lambda: any(r.ok is not None for r in sim_s.liveliness().get("hydro/monitor/m", timeout=1.0)),
                     30, "the monitor")
            sim.start()
            yield latest, seen
        finally:
            stop.set()
            mon.join(30)
            sim.join(30)


@pytest.mark.network
@pytest.mark.timeout(120)
def test_a_rig_is_graded_only_once_its_own_ranges_file_appears_and_keeps_them_over_a_bad_one(
        tmp_path, own_ranges, caplog):
    caplog.set_level(logging.WARNING, logger="hydromon.bus.monitor")
    spec = FleetSpec(rigs=[RigSpec(id="press-7", severity=0.7, base=BASE, config=CONFIG, noise="realistic")])
    with live_rig(tmp_path, spec, 4) as (latest, seen):
        wait_for(lambda: (h := latest()) is not None and h["seq"] > 1000, 60, "10 s of the rig")
        h = latest()
        assert (h["grade"], h["status"], h.get("ranges")) == ("unknown", "uncalibrated", None)
        own_ranges.save(tmp_path / "press-7.json")
        wait_for(lambda: (h := latest()) is not None and h.get("ranges") is not None and h["status"] == "ok",
                 30, "a verdict on the rig's own ranges")
        tag = latest()["ranges"]
        assert tag.startswith("press-7.json")
        wait_for(lambda: latest()["grade"] == "deterioration", 30, "the rig's true grade")
        (tmp_path / "press-7.json").write_text("{not json")
        wait_for(lambda: "ranges for rig press-7 refused" in caplog.text, 10, "the bad file refused")
        n = len(seen)
        wait_for(lambda: latest() is not None and len(seen) > n + 20, 10, "verdicts after the bad file")
        after = seen[n:]
        assert all(h["ranges"] == tag and h["grade"] == "deterioration" for h in after)
    refusals = [r for r in caplog.records if "refused" in r.getMessage()]
    assert len(refusals) == 1 and "press-7.json" in refusals[0].getMessage()


@pytest.mark.network
@pytest.mark.timeout(180)
def test_a_new_rig_is_commissioned_live_from_its_first_seconds_and_then_graded(tmp_path, caplog):
    caplog.set_level(logging.WARNING, logger="hydromon.bus.monitor")
    spec = FleetSpec(rigs=[RigSpec(id="press-8", base=BASE, config=CONFIG, noise="realistic")])  # healthy
    with live_rig(tmp_path, spec, 3, commission_new_s=15.0, commission_runs=10) as (latest, seen):
        wait_for(lambda: (h := latest()) is not None and h.get("ranges") is not None and h["status"] == "ok",
                 120, "a verdict on the rig's commissioned ranges")
    statuses = [h["status"] for h in seen]
    first_ok = statuses.index("ok")
    assert set(statuses[:first_ok]) == {"commissioning"}  # said from its first verdict until graded
    assert seen[first_ok - 1]["seq"] >= 1500  # its first 15 s went into the commissioning
    assert all(h["grade"] == "health" for h in seen[first_ok:])
    assert (tmp_path / "press-8.json").exists() and seen[-1]["ranges"].startswith("press-8.json")
    text = caplog.text
    assert "rig press-8: no ranges for it: COMMISSIONING it from its first 15 s" in text
    assert "rig press-8: COMMISSIONED from its first 15 s: ranges written to" in text
