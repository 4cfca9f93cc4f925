"""An overloaded monitor says so (``BacklogWatch``): batches drained full for a while mean its
input outpaces it, and health comes later and later; it says when it has caught up."""

from __future__ import annotations

import logging
import threading

import pytest
import zenoh

from helpers import wait_for, working_point_sample
from hydromon.bus.monitor import run_monitor
from hydromon.bus.session import listening_session, open_session
from hydromon.engine.core import MonitorCore
from hydromon.engine.watches import BacklogWatch
from hydromon.engine.warm import warm_up


def test_full_batches_for_a_while_are_told_once_and_the_catch_up_after():
    w = BacklogWatch(max_batch=100, after=2.0)
    assert w.observe(100, 10.0) is None  # full from t = 10
    assert w.observe(100, 11.0) is None
    told = w.observe(100, 12.0)
    assert told is not None and "behind its input for 2.0 s" in told and "150 a second" in told
    assert "--rigs" in told  # what to do about it
    assert w.observe(100, 13.0) is None  # once per run of full batches
    assert w.observe(99, 14.5) == "monitor: caught up after 4.5 s behind its input"
    assert (w.episodes, w.seconds) == (1, 4.5)
    assert w.observe(99, 15.0) is None and w.close(16.0) is None


def test_a_start_up_burst_says_nothing():
    w = BacklogWatch(max_batch=100, after=2.0)
    for t in (0.0, 0.5, 1.0, 1.9):
        assert w.observe(100, t) is None
    assert w.observe(3, 2.5) is None  # drained before `after`: not reported, not counted
    assert (w.episodes, w.seconds) == (0, 0.0)
    # a later run of full batches is timed from its own start
    for t in (10.0, 11.0):
        assert w.observe(100, t) is None
    assert w.observe(100, 12.0) is not None


def test_stopping_while_behind_is_said():
    w = BacklogWatch(max_batch=10, after=1.0)
    w.observe(10, 0.0)
    assert w.observe(10, 1.0) is not None
    assert w.close(3.0) == "monitor: stopped while still behind after 3.0 s behind its input"


@pytest.mark.parametrize("max_batch, after", [(0, 2.0), (10, 0.0), (10, -1.0), (10, float("nan"))])
def test_bad_arguments_are_refused(max_batch, after):
    with pytest.raises(ValueError):
        BacklogWatch(max_batch, after)


@pytest.mark.network
@pytest.mark.timeout(600)  # a fresh checkout compiles the kernels first (about a minute here)
def test_a_monitor_node_behind_its_input_says_so_then_catches_up(caplog):
    """Loopback: 20,000 samples put at once, a monitor that takes two a batch (a batch costs it
    tens of microseconds, a put a few): the queue holds thousands for a while, then drains."""
    warm_up()  # here, not in the node's thread, so the waits below do not include compiling
    n = 20_000
    core = MonitorCore(eval_every=10)
    with listening_session() as (mon_s, ep), open_session("peer", connect=[ep]) as pub_s, \
            caplog.at_level(logging.WARNING, logger="hydromon.bus.monitor"):
        stop = threading.Event()
        mon = threading.Thread(target=lambda: run_monitor(mon_s, stop_event=stop, node_name="behind", core=core,
                                                          max_batch=2, behind_after_s=0.05,
                                                          stale_after_s=None), daemon=True)
        mon.start()
        try:
            wait_for(lambda: any(r.ok is not None for r in pub_s.liveliness().get("hydro/monitor/*", timeout=1.0)),
                     30, "the monitor's liveliness token")
            # blocking as the rigs' publishers do: a dropping one loses samples of this burst when
            # the machine is busy, and the monitor then waits for samples that never come
            pub = pub_s.declare_publisher("hydro/rig/flood/sample", congestion_control=zenoh.CongestionControl.BLOCK)
            for seq in range(n):
                pub.put(working_point_sample(seq))
            wait_for(lambda: core.counters.accepted == n, 90, f"the {n} samples")
            wait_for(lambda: any("caught up" in r.getMessage() for r in caplog.records), 30, "the catch-up line")
        finally:
            stop.set()
            mon.join(30)
    lines = [r.getMessage() for r in caplog.records]
    behind = [m for m in lines if "behind its input for" in m]
    assert len(behind) >= 1 and "every batch drained full (2 messages)" in behind[0], lines
    assert lines.index(behind[0]) < next(i for i, m in enumerate(lines) if "caught up" in m)
    assert core.counters.dropped_seq == 0 and core.counters.gaps == 0  # nothing lost meanwhile
