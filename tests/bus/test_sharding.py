"""Sharding a plant over several monitors by a rig-id key expression (``hydromon monitor --rigs``)."""

import threading

import pytest

from helpers import health_seqs, wait_for, window_end  # noqa: F401
from hydromon.bus.monitor import rig_pattern, run_monitor
from hydromon.bus.session import listening_session, open_session
from hydromon.bus.sim import run_sim
from hydromon.engine.core import MonitorCore
from hydromon.store.fleetfile import default_fleet


def test_rig_pattern_validation():
    assert rig_pattern("*") == "*"
    assert rig_pattern("line1-*") == "line1-$*"
    for bad in ("**", "a/b", "bad id", "", "x" * 65):
        with pytest.raises(ValueError, match="rig pattern"):
            rig_pattern(bad)


@pytest.mark.network
@pytest.mark.timeout(120)
def test_two_monitors_split_the_rigs_between_them():
    spec = default_fleet()  # table4-g1 .. table4-g5
    seconds = 3.0
    with listening_session() as (sim_s, ep), open_session("peer", connect=[ep]) as a_s, \
            open_session("peer", connect=[ep]) as b_s:
        shards = {"a": (a_s, "table4-g1"), "b": (b_s, "table4-g$*")}  # g1 alone; every table4-g rig
        stop, cores = threading.Event(), {n: MonitorCore() for n in shards}
        threads = [threading.Thread(target=run_monitor, args=(s,), daemon=True, kwargs={
            "stop_event": stop, "node_name": f"shard-{n}", "rigs": p, "core": cores[n]}) for n, (s, p) in shards.items()]
        for t in threads:
            t.start()
        n = int(seconds * 100)
        try:
            for name in shards:
                wait_for(lambda name=name: any(r.ok is not None for r in sim_s.liveliness().get(
                    f"hydro/monitor/shard-{name}", timeout=1.0)), 60, f"monitor {name}")
            run_sim(sim_s, spec, rate=0, duration=seconds)
            wait_for(lambda: cores["a"].counters.accepted >= n and cores["b"].counters.accepted >= 5 * n, 60,
                     "both monitors to take every sample of their rigs")
        finally:
            stop.set()
            for t in threads:
                t.join(30)
    assert not any(t.is_alive() for t in threads)
    assert sorted(cores["a"].rigs) == ["table4-g1"]
    assert sorted(cores["b"].rigs) == [f"table4-g{i}" for i in range(1, 6)]
    assert cores["a"].counters.accepted == n and cores["b"].counters.accepted == 5 * n
