"""Payloads too large to be one of ours (more than ``PAYLOAD_MAX`` bytes) on a real zenoh bus
(loopback): the monitor node counts them unread, flags the rig they came for, and grades the
rigs around them as without them."""

from __future__ import annotations

import threading

import orjson
import pytest
import zenoh

from helpers import health_seqs, sample_with, wait_for
from hydromon.bus.monitor import run_monitor
from hydromon.bus.session import JSON, listening_session, open_session
from hydromon.engine.core import MonitorCore
from hydromon.engine.validate import PAYLOAD_MAX
from hydromon.store.fleetfile import FleetSpec, RigSpec
from hydromon.store.simfiles import iter_blocks

BLOCK = zenoh.CongestionControl.BLOCK


def _messages(rig: str, n: int) -> list[tuple[str, bytes]]:
    fleet = FleetSpec(rigs=[RigSpec(id=rig, table4=3)]).build()
    out = []
    for blk in iter_blocks(fleet, n, block=100):
        for seq, t, row in zip(blk.seq.tolist(), blk.t.tolist(), blk.samples[0].tolist()):
            out.append((f"hydro/rig/{rig}/sample", orjson.dumps(dict(zip(("seq", "t", "ug", "x1", "x3", "x4", "x5"),
                                                                          (seq, t, *row))))))
    return out


@pytest.mark.network
@pytest.mark.timeout(120)
@pytest.mark.parametrize("poll_s", [0.005, 3.0])  # batches as they come, or everything in one batch
def test_payloads_beyond_the_limit_are_counted_unread_and_flag_their_rig(poll_s):
    n = 400
    good = _messages("r1", n)
    big = sample_with()[:-1] + b" " * PAYLOAD_MAX + b"}"  # valid JSON, padded past the limit
    # r1's junk on its own sample key (one FIFO with its samples, so in its place among them); the frame
    # key's under a rig of no samples (the node drains frames after samples: on r1's it could land a
    # batch later)
    junk = {150: ("hydro/rig/r1/sample", big), 151: ("hydro/rig/other/sample", big),
            152: ("hydro/rig/other/frame", big)}
    with listening_session() as (mon_s, ep), open_session("peer", connect=[ep]) as pub_s:
        sub = pub_s.declare_subscriber("hydro/rig/*/health", zenoh.handlers.FifoChannel(10000))
        stop, result = threading.Event(), {}
        mon = threading.Thread(target=lambda: result.update(core=run_monitor(mon_s, stop_event=stop, node_name="m1",
                                                                             stale_after_s=None, poll_s=poll_s)),
                               daemon=True)
        mon.start()
        got = []
        try:
            wait_for(lambda: any(r.ok is not None for r in pub_s.liveliness().get("hydro/monitor/m1", timeout=1.0)),
                     60, "the monitor's liveliness token")
            for i, (key, payload) in enumerate(good):
                pub_s.put(key, payload, encoding=JSON, congestion_control=BLOCK)
                if i in junk:
                    pub_s.put(*junk[i], encoding=JSON, congestion_control=BLOCK)

            def drain():
                while (m := sub.try_recv()) is not None:
                    got.append(orjson.loads(m.payload.to_bytes()))
                return bool(got) and got[-1]["seq"] == health_seqs("r1", n)[-1]

            wait_for(drain, 60, "the last health of r1")
        finally:
            stop.set()
            mon.join(30)
    core = result["core"]
    assert core.counters.rejected["too-large"] == 3 and sum(core.counters.rejected.values()) == 3
    assert list(core.rigs) == ["r1"]  # the other rig's junk made it no rig
    # r1's health: its window with the junk says bad-input, and every other is what it is without the junk
    clean = [orjson.loads(p) for _, p in MonitorCore().process(good)]
    statuses = [h["status"] for h in got]
    flagged = [i for i, s in enumerate(statuses) if s == "bad-input"]
    assert len(got) == len(clean) and len(flagged) == 1, statuses
    assert all(150 <= got[i]["seq"] < 200 for i in flagged), statuses
    for i, (h, c) in enumerate(zip(got, clean)):
        h.pop("node", None), h.pop("epoch", None)
        if i not in flagged:
            assert h == c
