"""Sharding a plant over several monitors by a rig-id key expression (``hydromon monitor --rigs``)."""

import threading
import time

import pytest

from hydromon.bus import free_tcp_endpoint, open_session
from hydromon.fleetfile import default_fleet
from hydromon.monitornode import rig_pattern, run_monitor
from hydromon.simnode import run_sim
from helpers import health_seqs, wait_for, window_end  # noqa: F401


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
    ep = free_tcp_endpoint()
    seconds = 3.0
    with open_session("peer", listen=[ep]) as sim_s, open_session("peer", connect=[ep]) as a_s, \
            open_session("peer", connect=[ep]) as b_s:
        stop, cores = threading.Event(), {}
        shards = {"a": (a_s, "table4-g1"), "b": (b_s, "table4-g$*")}  # g1 alone; every table4-g rig
        threads = [threading.Thread(target=lambda n=n, s=s, p=p: cores.update({n: run_monitor(
            s, stop_event=stop, node_name=f"shard-{n}", rigs=p)}), daemon=True) for n, (s, p) in shards.items()]
        for t in threads:
            t.start()
        try:
            for n in shards:
                wait_for(lambda n=n: any(r.ok is not None for r in sim_s.liveliness().get(
                    f"hydro/monitor/shard-{n}", timeout=1.0)), 60, f"monitor {n}")
            run_sim(sim_s, spec, rate=0, duration=seconds)
            time.sleep(1.0)
        finally:
            stop.set()
            for t in threads:
                t.join(30)
    assert sorted(cores["a"].rigs) == ["table4-g1"]
    assert sorted(cores["b"].rigs) == [f"table4-g{i}" for i in range(1, 6)]
    assert cores["a"].counters.accepted == int(seconds * 100)
