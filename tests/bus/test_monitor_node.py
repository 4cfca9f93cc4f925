"""The monitor node on real zenoh sessions on loopback: grades, queries, namespaces, late joiners, its exit summary; its rig keys declared on the session."""

from __future__ import annotations

import threading

import orjson
import pytest
import zenoh

from helpers import health_seqs, wait_for
from hydromon.bus.monitor import run_monitor
from hydromon.bus.session import listening_session, open_session
from hydromon.bus.sim import run_sim
from hydromon.contract import Health, RigConfig, event_key, health_key
from hydromon.engine.core import MonitorCore
from hydromon.engine.samples import sample_payload
from hydromon.engine.watches import RateLimitedLog
from hydromon.store.fleetfile import FleetSpec, default_fleet
from plant_sim.degradation import TABLE4_PAPER_GRADES

NS = "hydro"


SPEC = default_fleet()


@pytest.mark.network
@pytest.mark.timeout(90)
def test_sim_and_monitor_on_loopback_give_the_true_grades_and_answer_queries():
    seconds = 8.0
    n = int(seconds * 100)
    with listening_session() as (mon_s, ep), open_session("peer", connect=[ep]) as sim_s, \
            open_session("peer", connect=[ep]) as obs_s:
        sub = obs_s.declare_subscriber("hydro/rig/*/health", zenoh.handlers.FifoChannel(100000))
        stop, result = threading.Event(), {}
        mon = threading.Thread(target=lambda: result.update(core=run_monitor(mon_s, stop_event=stop, node_name="m1",
                                                                                     stale_after_s=None)),
                               daemon=True)
        mon.start()
        try:
            # the token is declared after the subscriptions: once the sim sees it, nothing is lost
            wait_for(lambda: any(r.ok is not None for r in sim_s.liveliness().get("hydro/monitor/*", timeout=1.0)),
                  30, "the monitor's liveliness token")
            stats = run_sim(sim_s, SPEC, rate=0, duration=seconds)
            assert stats.samples == n
            got: dict[str, list[Health]] = {}

            def drain():
                while (m := sub.try_recv()) is not None:
                    got.setdefault(str(m.key_expr).split("/")[2], []).append(
                        Health.model_validate_json(m.payload.to_bytes()))
                return len(got) == 5 and all(h[-1].seq == health_seqs(r, n)[-1] for r, h in got.items())

            wait_for(drain, 60, "the last health message of every rig")
            replies = [r.ok for r in obs_s.get("hydro/rig/*/health", timeout=5.0) if r.ok is not None]
            one = [r.ok for r in obs_s.get("hydro/rig/table4-g4/health", timeout=5.0) if r.ok is not None]
        finally:
            stop.set()
            mon.join(30)
        assert not mon.is_alive()
    core = result["core"]
    c = core.counters
    assert c.accepted == 5 * n and c.gaps == 0 and c.dropped_seq == 0 and c.rejected_total == 0
    assert c.configs == 5
    for rig, hs in got.items():
        assert [h.seq for h in hs] == health_seqs(rig, n)  # every verdict, in order
        assert hs[-1].status == "ok" and hs[-1].grade == TABLE4_PAPER_GRADES[int(rig[-1])]
    assert sorted(str(r.key_expr) for r in replies) == sorted(health_key(i) for i in SPEC.ids)
    for r in replies:
        rig = str(r.key_expr).split("/")[2]
        assert Health.model_validate_json(r.payload.to_bytes()) == got[rig][-1]
    assert [str(r.key_expr) for r in one] == [health_key("table4-g4")]


@pytest.mark.network
@pytest.mark.timeout(90)
def test_a_rig_that_stops_publishing_goes_stale_on_the_bus_and_on_the_query():
    spec = FleetSpec(rigs=SPEC.rigs[:1])
    rig = spec.ids[0]
    with listening_session() as (mon_s, ep), open_session("peer", connect=[ep]) as sim_s, \
            open_session("peer", connect=[ep]) as obs_s:
        sub = obs_s.declare_subscriber("hydro/rig/*/health", zenoh.handlers.FifoChannel(10000))
        stop = threading.Event()
        mon = threading.Thread(target=lambda: run_monitor(mon_s, stop_event=stop, node_name="m3", stale_after_s=0.5),
                               daemon=True)
        mon.start()
        try:
            wait_for(lambda: any(r.ok is not None for r in sim_s.liveliness().get("hydro/monitor/m3", timeout=1.0)),
                     60, "the monitor's liveliness token")
            run_sim(sim_s, spec, rate=0, duration=1.0)  # then the rig falls silent
            got = []

            def drain():
                while (m := sub.try_recv()) is not None:
                    got.append(orjson.loads(m.payload.to_bytes()))
                return bool(got) and got[-1]["status"] == "stale"

            wait_for(drain, 30, "a stale health of the silent rig")
            replies = [orjson.loads(r.ok.payload.to_bytes()) for r in obs_s.get(f"hydro/rig/{rig}/health", timeout=5.0)
                       if r.ok is not None]
        finally:
            stop.set()
            mon.join(30)
        assert not mon.is_alive()
    assert [h["status"] for h in got].count("stale") == 1 and got[-1]["seq"] == health_seqs(rig, 100)[-1]
    assert got[-1] == {**got[-2], "status": "stale"}  # the last verdict, re-sent stale
    assert replies == [got[-1]]


@pytest.mark.network
@pytest.mark.timeout(120)
def test_a_monitor_in_namespace_site2_on_loopback_ignores_hydro_traffic():
    spec = FleetSpec(rigs=SPEC.rigs[:2])
    seconds = 2.0
    n = int(seconds * 100)
    with listening_session() as (mon_s, ep), open_session("peer", connect=[ep]) as sim_s, \
            open_session("peer", connect=[ep]) as obs_s:
        site2_sub = obs_s.declare_subscriber("site2/rig/*/health", zenoh.handlers.FifoChannel(10000))
        hydro_sub = obs_s.declare_subscriber("hydro/rig/*/health", zenoh.handlers.FifoChannel(10000))
        stop, core = threading.Event(), MonitorCore("site2")
        mon = threading.Thread(target=lambda: run_monitor(mon_s, namespace="site2", stop_event=stop, node_name="m2",
                                                          core=core, stale_after_s=None), daemon=True)
        mon.start()
        try:
            wait_for(lambda: any(r.ok is not None for r in sim_s.liveliness().get("site2/monitor/m2", timeout=1.0)),
                     60, "the monitor's liveliness token under site2")
            run_sim(sim_s, spec, namespace="hydro", rate=0, duration=seconds)  # not for this monitor
            run_sim(sim_s, spec, namespace="site2", rate=0, duration=seconds)
            got: dict[str, list[int]] = {}

            def drain():
                while (m := site2_sub.try_recv()) is not None:
                    got.setdefault(str(m.key_expr), []).append(orjson.loads(m.payload.to_bytes())["seq"])
                return len(got) == 2 and all(s[-1] == health_seqs(k.split("/")[2], n)[-1] for k, s in got.items())

            wait_for(drain, 60, "the last site2 health message of every rig")
            replies = [str(r.ok.key_expr) for r in obs_s.get("site2/rig/*/health", timeout=5.0) if r.ok is not None]
        finally:
            stop.set()
            mon.join(30)
        assert not mon.is_alive()
        hydro_health = []
        while (m := hydro_sub.try_recv()) is not None:
            hydro_health.append(str(m.key_expr))
    c = core.counters
    assert c.accepted == 2 * n and c.configs == 2 and c.rejected_total == 0 and c.dropped_seq == 0
    assert sorted(got) == sorted(replies) == sorted(f"site2/rig/{i}/health" for i in spec.ids)
    for key, seqs in got.items():
        assert seqs == health_seqs(key.split("/")[2], n)
    assert hydro_health == []


class _RepliesSeen:
    """A session for run_monitor that records the keys of the query replies it takes
    (everything else goes to the real session)."""

    def __init__(self, session: zenoh.Session):
        self._session, self.replies = session, []

    def __getattr__(self, name):
        return getattr(self._session, name)

    def get(self, *args, **kwargs):
        handler, seen = self._session.get(*args, **kwargs), self.replies

        class Recording:
            def try_recv(self):
                r = handler.try_recv()
                if r is not None and r.ok is not None:
                    seen.append(str(r.ok.key_expr))
                return r

        return Recording()


@pytest.mark.network
@pytest.mark.timeout(90)
def test_a_monitor_started_late_asks_the_running_rigs_for_their_configs():
    spec = FleetSpec(config=RigConfig(F_L=3500.0, p_s=11e6), rigs=SPEC.rigs[:2])
    config_keys = sorted(f"{NS}/rig/{i}/config" for i in spec.ids)
    with listening_session() as (sim_s, ep), open_session("peer", connect=[ep]) as mon_s, \
            open_session("peer", connect=[ep]) as probe_s:
        probe = probe_s.declare_subscriber(f"{NS}/rig/*/config", zenoh.handlers.FifoChannel(64))
        # the sim's session knows of the probe's subscription before the sim publishes
        check = sim_s.declare_publisher(config_keys[0])
        wait_for(lambda: check.matching_status.matching, 30, "the probe's subscription")
        check.undeclare()
        stop_sim, stop_mon, result = threading.Event(), threading.Event(), {}
        sim = threading.Thread(target=lambda: result.update(sim=run_sim(sim_s, spec, rate=1.0, stop_event=stop_sim)),
                               daemon=True)
        sim.start()  # publishes the configs once, now, while no monitor listens
        seen = []

        def configs_out():
            while (m := probe.try_recv()) is not None:
                seen.append(str(m.key_expr))
            return set(seen) == set(config_keys)

        core, recording = MonitorCore(), _RepliesSeen(mon_s)
        mon = threading.Thread(target=lambda: result.update(core=run_monitor(recording, stop_event=stop_mon,
                                                                             core=core, stale_after_s=None)), daemon=True)
        try:
            wait_for(configs_out, 60, "the sim's configs")
            mon.start()  # subscribes only now: the configs can reach it only as replies to its query
            wait_for(lambda: len(core.configs) == 2 and core.counters.accepted > 0, 30, "the configs by query")
        finally:
            stop_sim.set()
            sim.join(30)
            stop_mon.set()
            mon.join(30)
        configs_out()
    assert not sim.is_alive() and not mon.is_alive()
    assert core.configs == {r.id: spec.config for r in spec.rigs}
    assert core.counters.configs == 2 and core.counters.rejected_total == 0
    # both came as replies to the monitor's query, and the sim published them only the once the
    # probe saw (before the monitor subscribed): no config reached the monitor by subscription
    assert sorted(recording.replies) == config_keys
    assert result["sim"].configs_published == 2 and sorted(seen) == config_keys


@pytest.mark.network
@pytest.mark.timeout(60)
def test_monitor_node_reports_its_suppressed_rejections_when_it_stops(caplog):
    log = RateLimitedLog(interval=3600.0)  # nothing falls due while it runs: only the stop reports
    core = MonitorCore(on_reject=log)
    with listening_session() as (mon_s, ep), open_session("peer", connect=[ep]) as pub_s, \
            caplog.at_level("WARNING", logger="hydromon.bus.monitor"):
        stop = threading.Event()
        mon = threading.Thread(target=lambda: run_monitor(mon_s, stop_event=stop, node_name="m4", core=core),
                               daemon=True)
        mon.start()
        try:
            wait_for(lambda: any(r.ok is not None for r in pub_s.liveliness().get("hydro/monitor/*", timeout=1.0)),
                     30, "the monitor's liveliness token")
            for _ in range(5):
                pub_s.put("hydro/rig/a/sample", b"not json")
            wait_for(lambda: core.counters.rejected_total == 5, 30, "the 5 rejections")
        finally:
            stop.set()
            mon.join(30)
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith("rejected not-json")]
    assert len(lines) == 2 and lines[1] == "rejected not-json: 4 more since the last report"


def _still_running(proc) -> None:
    if proc.poll() is not None:
        raise AssertionError(f"the monitor exited early ({proc.returncode}): {proc.stderr.read()[-2000:]}")


@pytest.mark.network
@pytest.mark.timeout(90)
def test_monitor_command_runs_for_its_duration_and_reports_its_counts():
    import os
    import subprocess
    import sys

    # this session listens and the monitor connects to it: the monitor's session is up as soon as
    # it opens. The other way round (monitor --listen, this session --connect before the process
    # listened), zenoh's connect retries back off to every 4 s, and up to 4 s of the monitor's
    # 6 s went by before this session reached it: under load the 600 samples then did not all get
    # in before the monitor stopped (reproduced: "540 samples, 54 health messages").
    with listening_session() as (s, ep):
        proc = subprocess.Popen([sys.executable, "-m", "hydromon.cli", "monitor", "--connect", ep, "--duration", "6",
                                 "--node", "cli-mon"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                env={**os.environ, "PYTHONUNBUFFERED": "1"})
        try:
            wait_for(lambda: any(r.ok is not None for r in s.liveliness().get("hydro/monitor/cli-mon", timeout=1.0)),
                     60, "the monitor process", alive=lambda: _still_running(proc))
            run_sim(s, FleetSpec(rigs=SPEC.rigs[:2]), rate=0, duration=3.0)
            s.put("hydro/rig/x/sample", b"{oops")
            _, err = proc.communicate(timeout=60)
        finally:
            proc.kill()
    assert proc.returncode == 0, err
    assert "2 rig(s), 600 samples, 60 health messages; rejected: not-json 1;" in err


class _KeySession:
    """What RigKeys uses of a session: declare_keyexpr and undeclare, recorded."""

    def __init__(self):
        self.declared, self.undeclared = [], []

    def declare_keyexpr(self, key):
        self.declared.append(key)
        return ("ke", key)

    def undeclare(self, ke):
        self.undeclared.append(ke[1])


def _core_with(rig_ids):
    core = MonitorCore(NS)
    for i, rig in enumerate(rig_ids):
        core.process([(f"{NS}/rig/{rig}/sample", sample_payload(0, 0.0, [2.0, 0.0, 6e6, 6e6, 0.0]))])
    return core


def test_rig_keys_declares_each_rigs_sample_health_and_event_key_once_and_undeclares_them():
    from hydromon.bus.rig_keys import RigKeys

    session, core = _KeySession(), _core_with(["a", "b"])
    keys = RigKeys(session, NS)
    keys.sync(core)
    keys.sync(core)
    leaves = ("sample", "health", "event")
    assert sorted(session.declared) == sorted(f"{NS}/rig/{r}/{leaf}" for r in "ab" for leaf in leaves)
    assert keys.health[health_key("a", NS)] == ("ke", health_key("a", NS))
    assert keys.events[event_key("a", NS)] == ("ke", event_key("a", NS))
    core.process([(f"{NS}/rig/c/sample", sample_payload(0, 0.0, [2.0, 0.0, 6e6, 6e6, 0.0]))])
    keys.sync(core)
    assert len(session.declared) == 9 and session.declared[-3:] == [f"{NS}/rig/c/{leaf}" for leaf in leaves]
    keys.forget(core.forget(["a"]))
    assert sorted(session.undeclared) == sorted(f"{NS}/rig/a/{leaf}" for leaf in leaves)
    assert health_key("a", NS) not in keys.health and event_key("a", NS) not in keys.events
    keys.close()
    assert sorted(session.undeclared) == sorted(session.declared) and not keys.health and not keys.events
    assert not keys.off


def test_rig_keys_declares_a_fleet_starting_at_once_over_several_calls():
    from hydromon.bus.rig_keys import RigKeys

    session, core = _KeySession(), _core_with(["a", "b", "c"])
    keys = RigKeys(session, NS, per_sync=2)
    keys.sync(core)
    assert sorted(keys.rigs) == ["a", "b"] and len(session.declared) == 6
    keys.sync(core)
    assert sorted(keys.rigs) == ["a", "b", "c"] and len(session.declared) == 9
    keys.sync(core)
    assert len(session.declared) == 9


def test_rig_keys_gives_up_beyond_its_rig_limit_and_on_a_flood_of_rejects():
    from hydromon.bus.rig_keys import RigKeys

    session, core = _KeySession(), _core_with(["a", "b", "c"])
    keys = RigKeys(session, NS, max_rigs=2)
    keys.sync(core)
    assert keys.off and session.declared == [] and keys.health == {}
    session, core = _KeySession(), _core_with(["a"])
    keys = RigKeys(session, NS, max_rejects=3)
    keys.sync(core)
    keys.check(core)
    core.process([(f"{NS}/rig/bad.id/sample", b"{}")] * 3)
    keys.check(core)
    assert not keys.off  # 3 rejects since the last check: not more than max_rejects
    core.process([(f"{NS}/rig/bad.id/sample", b"{}")] * 4)
    keys.check(core)
    assert keys.off and sorted(session.undeclared) == sorted(session.declared) and len(session.declared) == 3
    core.process([(f"{NS}/rig/d/sample", sample_payload(0, 0.0, [2.0, 0.0, 6e6, 6e6, 0.0]))])
    keys.sync(core)
    assert len(session.declared) == 3  # off for good
