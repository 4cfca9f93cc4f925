"""End to end with every node a separate OS process on loopback, through a router.

``hydromon router``, ``hydromon monitor``, ``hydromon record`` and ``hydromon sim`` (the five
Table 4 rigs, 30 s of rig time at 10x real time) run as processes, the nodes as clients of
the router; the test process is a client too and collects the published health. Every rig's
published grade must be its true grade by the end of the 30 s. The recorder is then stopped
with SIGINT and its recording must replay to the health stored in it, byte for byte: directly
(``replay_direct``) and over the bus (a ``hydromon replay`` process into a fresh monitor).

Subscribers come up before the sim starts (the monitor's liveliness token, the recorder's
subscription seen through a probe key only it matches), since zenoh drops what is published
before a route exists. Multicast scouting is off (the nodes' default); every process is
stopped in a ``finally``; every wait is bounded.
"""

from __future__ import annotations

import io
import threading

import orjson
import pytest
import zenoh

from helpers import Procs, health_seqs, held_port, taken_first, wait_for, without_node
from hydromon.bus.monitor import run_monitor
from hydromon.bus.session import open_session
from hydromon.contract import Health
from hydromon.store.fleetfile import default_fleet, true_grade
from hydromon.store.mcap_layout import MAGIC
from hydromon.store.mcap_read import read_recording
from hydromon.store.mcap_recover import recover
from hydromon.store.replay import replay_direct

SECONDS = 30
RATE = 10
N = SECONDS * 100  # samples per rig


def _messages_on_disk(path) -> int:
    """Messages readable from a snapshot of a recording that is still being written."""
    data = path.read_bytes() if path.exists() else b""
    if len(data) < len(MAGIC):  # just created: recover refuses what is shorter than the magic
        return 0
    return recover(io.BytesIO(data), io.BytesIO()).messages


def _warm_kernels() -> None:
    """Run the plant and monitor kernels once here, so a stale numba cache is rebuilt by this
    process before the node processes start (they then load it instead of compiling)."""
    from hydromon.engine.core import MonitorCore
    from hydromon.store.fleetfile import FleetSpec, RigSpec
    from hydromon.store.simfiles import iter_blocks

    fleet = FleetSpec(rigs=[RigSpec(id="warm", table4=1)]).build()
    msgs = [("hydro/rig/warm/sample", orjson.dumps(dict(zip(("seq", "t", "ug", "x1", "x3", "x4", "x5"),
                                                             (s, t, *row)))))
            for blk in iter_blocks(fleet, 100) for s, t, row in zip(blk.seq.tolist(), blk.t.tolist(),
                                                                    blk.samples[0].tolist())]
    assert len(MonitorCore().process(msgs)) == 10


def _by_key(msgs):
    out: dict[str, list[bytes]] = {}
    for k, p in msgs:
        out.setdefault(k, []).append(p)
    return out


@pytest.mark.network
@pytest.mark.timeout(400)
def test_router_sim_monitor_recorder_as_processes_then_replay(tmp_path):
    _warm_kernels()
    spec = default_fleet()
    truth = {r.id: true_grade(r) for r in spec.rigs}
    out = tmp_path / "e2e.mcap"
    procs = Procs(tmp_path)
    live: list[tuple[str, bytes]] = []
    try:
        ep = procs.start_listening("router", "router", ready="listening on")
        bus = ["--mode", "client", "--connect", ep]
        # the recording is compared with direct replay, which has no clock: no re-sent stale health
        # if this machine is slow to stop the monitor after the sim (--stale-after)
        # and direct replay's default memory, a growing window (the live monitor's default is 60 s)
        procs.start("monitor", "monitor", "--node", "e2e", "--stale-after", "600", "--memory", "none", *bus)
        procs.start("record", "record", "--out", str(out), *bus)
        with open_session("client", connect=[ep]) as s:
            sub = s.declare_subscriber("hydro/rig/*/health", zenoh.handlers.FifoChannel(100_000))
            probe = s.declare_publisher("hydro/e2e-probe")  # under hydro/**: only the recorder matches it
            wait_for(lambda: probe.matching_status.matching, 180, "the recorder's subscription", alive=procs.check_alive)
            probe.undeclare()
            wait_for(lambda: any(r.ok is not None for r in s.liveliness().get("hydro/monitor/e2e", timeout=1.0)),
                     180, "the monitor's liveliness token", alive=procs.check_alive)
            procs.start("sim", "sim", "--rate", str(RATE), "--duration", str(SECONDS), *bus)

            def drain() -> bool:
                while (m := sub.try_recv()) is not None:
                    live.append((str(m.key_expr), m.payload.to_bytes()))
                last = {}
                for k, p in live:
                    last[k.split("/")[2]] = p
                return sorted(last) == sorted(truth) and all(orjson.loads(p)["seq"] == health_seqs(r, N)[-1]
                                                             for r, p in last.items())

            wait_for(drain, 240, "the last health of every rig", alive=procs.check_alive)
            assert procs.wait("sim", 60) == 0, procs.log("sim")
        assert procs.stop("monitor") == 0, procs.log("monitor")
        # the recorder has every config, sample and verdict on disk (flushed within 0.5 s)
        n_health = sum(len(health_seqs(r, N)) for r in truth)
        want = 5 + 5 * N + n_health
        wait_for(lambda: _messages_on_disk(out) >= want, 60, f"{want} messages in the live recording", alive=procs.check_alive)
        assert procs.stop("record") == 0, procs.log("record")

        # -- live: every verdict of every rig, in order; the final grade is the true grade
        got = _by_key(live)
        for rig, grade in truth.items():
            hs = [Health.model_validate_json(p) for p in got[f"hydro/rig/{rig}/health"]]
            assert [h.seq for h in hs] == health_seqs(rig, N)
            assert hs[-1].t <= SECONDS and hs[-1].status == "ok"
            assert hs[-1].grade == grade, f"{rig}: {hs[-1].grade}, true grade {grade}"
        mon_log = procs.log("monitor")
        assert (f"5 rig(s), {5 * N} samples, {n_health} health messages; rejected: none; dropped seq 0, "
                f"gaps 0 (0 samples missing), restarts 0") in mon_log, mon_log
        assert str(out) in procs.log("record")

        # -- the recording: complete (it has its summary: a clean stop), the live verdicts in it
        msgs = list(read_recording(out))
        kinds = [k.rsplit("/", 1)[1] for k, _, _, _ in msgs]
        assert (kinds.count("config"), kinds.count("sample"), kinds.count("health")) == (5, 5 * N, n_health)
        stored = [(k, p) for k, p, _, _ in msgs if k.endswith("/health")]
        assert _by_key(stored) == got

        # -- direct replay: the stored health, byte for byte and in the same order
        direct, core = replay_direct(out)
        stored = [(k, without_node(p)) for k, p in stored]  # a replay's monitor is another node
        assert direct == stored
        assert core.counters.accepted == 5 * N and core.counters.rejected_total == 0

        # -- bus replay: a `hydromon replay` process into a fresh monitor (in this process)
        replayed: list[tuple[str, bytes]] = []
        stop = threading.Event()
        result = {}
        with open_session("client", connect=[ep]) as s:
            mon = threading.Thread(target=lambda: result.update(core=run_monitor(
                s, node_name="e2e-replay", stop_event=stop, on_health=lambda k, p: replayed.append((k, p)),
                stale_after_s=None)),
                daemon=True)
            mon.start()
            try:
                wait_for(lambda: any(r.ok is not None for r in
                                  s.liveliness().get("hydro/monitor/e2e-replay", timeout=1.0)),
                         60, "the replay monitor's liveliness token", alive=procs.check_alive)
                procs.start("replay", "replay", str(out), "--rate", "0", "--quiet", "--wait", "60",
                            "--keys", "hydro/rig/*/sample", "--keys", "hydro/rig/*/config", *bus)
                assert procs.wait("replay", 120) == 0, procs.log("replay")
                wait_for(lambda: len(replayed) >= len(stored), 60, f"{len(stored)} verdicts of the bus replay")
            finally:
                stop.set()
                mon.join(30)
            assert not mon.is_alive()
        c = result["core"].counters
        assert (c.accepted, c.configs, c.rejected_total, c.dropped_seq, c.gaps) == (5 * N, 5, 0, 0, 0)
        assert replayed == stored
        assert "15005 messages on 10 key(s), 1 pass(es)" in procs.log("replay")
    finally:
        procs.close()


@pytest.mark.network
@pytest.mark.timeout(120)
def test_a_router_process_whose_port_was_taken_is_started_again_on_another(tmp_path, monkeypatch):
    held, taken = held_port()
    taken_first(monkeypatch, taken)
    procs = Procs(tmp_path)
    try:
        with held:
            ep = procs.start_listening("router", "router", ready="listening on")
        assert ep != taken and f"listening on {ep}" in procs.log("router")
        with open_session("client", connect=[ep]) as s:  # it is up there
            assert s.info.routers_zid()
        assert procs.stop("router") == 0
    finally:
        procs.close()
