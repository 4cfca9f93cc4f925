"""Frames on a real zenoh session on loopback: ``sim --frame`` into the monitor and the recorder
gives the health of the same samples sent one per message, byte for byte, and the recording
replays to it."""

from __future__ import annotations

import threading

import pytest
import zenoh

from helpers import by_rig, fleet_messages, health_seqs, wait_for
from hydromon.bus.monitor import run_monitor
from hydromon.bus.recorder import record
from hydromon.bus.session import listening_session, open_session
from hydromon.bus.sim import run_sim
from hydromon.contract import Health
from hydromon.engine.core import MonitorCore
from hydromon.store.fleetfile import default_fleet
from hydromon.store.replay import replay_direct

SPEC = default_fleet(noise="realistic")
SECONDS = 4.0
N = int(SECONDS * 100)


@pytest.mark.network
@pytest.mark.timeout(120)
def test_sim_frames_on_loopback_give_the_health_of_samples_byte_for_byte(tmp_path):
    want = by_rig(MonitorCore("hydro", node="m1", epoch=7).process(fleet_messages(SPEC, SECONDS)))
    out = tmp_path / "frames.mcap"
    with listening_session() as (mon_s, ep), open_session("peer", connect=[ep]) as sim_s, \
            open_session("peer", connect=[ep]) as obs_s, open_session("peer", connect=[ep]) as rec_s:
        sub = obs_s.declare_subscriber("hydro/rig/*/health", zenoh.handlers.FifoChannel(100000))
        stop, result = threading.Event(), {}
        core = MonitorCore("hydro", node="m1", epoch=7)
        mon = threading.Thread(target=lambda: run_monitor(mon_s, stop_event=stop, node_name="m1", core=core,
                                                          stale_after_s=None), daemon=True)
        frames = []
        rec = threading.Thread(target=lambda: result.update(r=record(
            rec_s, out, stop_event=stop, on_message=lambda key: key.endswith("/frame") and frames.append(key))),
            daemon=True)
        mon.start()
        rec.start()
        try:
            wait_for(lambda: any(r.ok is not None for r in sim_s.liveliness().get("hydro/monitor/*", timeout=1.0)),
                     30, "the monitor's liveliness token")
            probe = sim_s.declare_publisher("hydro/rig/table4-g1/frame")
            wait_for(lambda: probe.matching_status.matching, 20, "the subscriptions of the frame keys")
            probe.undeclare()
            wait_for(lambda: out.exists(), 20, "the recorder's file")
            stats = run_sim(sim_s, SPEC, rate=0, duration=SECONDS, frame=10)
            # frames end at each rig's phase: a short first and last one where it is not 0
            assert stats.samples == N and 5 * N // 10 <= stats.published <= 5 * (N // 10 + 1)
            got: dict[str, list[bytes]] = {}

            def drain():
                while (m := sub.try_recv()) is not None:
                    got.setdefault(str(m.key_expr).split("/")[2], []).append(m.payload.to_bytes())
                return len(got) == 5 and all(Health.model_validate_json(h[-1]).seq == health_seqs(r, N)[-1]
                                             for r, h in got.items())

            wait_for(drain, 60, "the last health message of every rig")
            wait_for(lambda: len(frames) == stats.published, 20, "the recorder's last frame")
        finally:
            stop.set()
            mon.join(30)
            rec.join(30)
    assert core.counters.accepted == 5 * N and core.counters.rejected_total == 0
    assert got == want  # byte for byte, every rig's health in order, at the same samples
    health, replayed = replay_direct(out, keys=["hydro/rig/*/frame", "hydro/rig/*/config"],
                                     core=MonitorCore("hydro", node="m1", epoch=7))
    assert replayed.counters.accepted == 5 * N and by_rig(health) == want
