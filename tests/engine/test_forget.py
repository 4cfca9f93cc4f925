"""Forgetting silent rigs (``MonitorCore.forget``, ``monitor --forget-after``): rows are reused
without a trace of the rig that had them, and rig ids that come and go never fill max_rigs."""

from __future__ import annotations

import logging
import threading

import orjson
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers import wait_for, working_point_sample
from hydromon.bus.monitor import run_monitor
from hydromon.bus.session import listening_session, open_session
from hydromon.contract import RigConfig
from hydromon.engine.core import MonitorCore
from hydromon.engine.watches import SilenceWatch


def _samples(rig: str, n: int, first: int = 0) -> list[tuple[str, bytes]]:
    return [(f"hydro/rig/{rig}/sample", working_point_sample(s)) for s in range(first, first + n)]


def _per_rig(out) -> dict:
    got: dict = {}
    for key, payload in out:
        got.setdefault(key, []).append(payload)
    return got


@settings(max_examples=40, deadline=None)
@given(n_old=st.integers(1, 4), forget=st.sets(st.integers(0, 3)), n_new=st.integers(1, 4),
       lengths=st.lists(st.integers(1, 40), min_size=8, max_size=8), interleave=st.booleans())
def test_a_reused_row_carries_nothing_of_its_forgotten_rig(n_old, forget, n_new, lengths, interleave):
    core = MonitorCore(eval_every=3)
    old = [f"old{i}" for i in range(n_old)]
    for i, rig in enumerate(old):
        core.process(_samples(rig, lengths[i]))
    gone = core.forget([old[i] for i in sorted(forget) if i < n_old] + ["never-seen"])
    assert gone == [old[i] for i in sorted(forget) if i < n_old]
    assert core.counters.forgotten == len(gone)
    assert not set(gone) & (set(core.rigs) | set(core.latest) | set(core.fleet.index))
    new = [f"new{i}" for i in range(n_new)]
    msgs = [_samples(rig, lengths[4 + i]) for i, rig in enumerate(new)]
    if interleave:  # the new rigs' samples mixed in one batch, and a kept old rig's with them
        flat = [m for group in zip(*[iter(g) for g in msgs]) for m in group] + sum((g[min(map(len, msgs)):] for g in msgs), [])
        out = core.process(flat + _samples(old[-1], 2, lengths[n_old - 1]) if old[-1] not in gone else flat)
    else:
        out = sum((core.process(g) for g in msgs), [])
    got = _per_rig(out)
    for rig, g in zip(new, msgs):
        fresh = MonitorCore(eval_every=3)
        want = _per_rig(fresh.process(g)).get(f"hydro/rig/{rig}/health", [])
        assert got.get(f"hydro/rig/{rig}/health", []) == want, rig  # byte for byte
    assert len(core.fleet.ids) == max(n_old, n_old - len(gone) + n_new)  # rows reused before any added


def test_a_forgotten_rig_that_comes_back_starts_afresh_with_its_config():
    core = MonitorCore(eval_every=3)
    conf = RigConfig(p_s=13e6)
    core.process([("hydro/rig/a/config", orjson.dumps(conf.model_dump()))] + _samples("a", 30))
    assert core.forget(["a"]) == ["a"]
    out = core.process(_samples("a", 30, first=500))  # its seq goes on: a new rig to the monitor
    fresh = MonitorCore(eval_every=3)
    want = fresh.process([("hydro/rig/a/config", orjson.dumps(conf.model_dump()))] + _samples("a", 30, first=500))
    assert out == want and core.rigs["a"].config == conf
    assert core.counters.gaps == 0 and core.counters.dropped_seq == 0


def test_rig_ids_that_come_and_go_never_fill_max_rigs():
    core = MonitorCore(eval_every=3, max_rigs=2)
    for i in range(10):
        rig = f"r{i}"
        core.process([(f"hydro/rig/{rig}/config", orjson.dumps(RigConfig().model_dump()))] + _samples(rig, 5))
        assert rig in core.rigs and core.rigs[rig].config is not None
        core.forget([rig])
    assert core.counters.rejected["too-many-rigs"] == 0
    assert len(core.fleet.ids) == 1  # one row, reused ten times
    assert len(core.configs) == 2  # the forgotten rigs' configs kept up to max_rigs, oldest dropped
    assert set(core.configs) == {"r8", "r9"}
    # without forgetting, the third rig id is refused, as before
    full = MonitorCore(eval_every=3, max_rigs=2)
    for i in range(3):
        full.process(_samples(f"r{i}", 5))
    assert full.counters.rejected["too-many-rigs"] == 5 and "r2" not in full.rigs


def test_silence_watch_forgets_after_its_time_only():
    core = MonitorCore(eval_every=3)
    core.process(_samples("a", 9) + _samples("b", 9))
    watch = SilenceWatch(2.0, forget_after=10.0)
    assert watch.forget_due(core, 0.0) == []
    core.process(_samples("b", 9, first=9))  # b keeps sending
    assert watch.forget_due(core, 5.0) == []
    assert [k for k, _ in watch.check(core, 5.0)] == ["hydro/rig/a/health"]  # stale first
    core.process(_samples("b", 9, first=18))
    assert watch.forget_due(core, 10.0) == ["a"]
    core.forget(["a"])
    assert watch.forget_due(core, 30.0) == ["b"]  # the freed row is never named
    with pytest.raises(ValueError, match="longer than stale after"):
        SilenceWatch(5.0, forget_after=5.0)
    with pytest.raises(ValueError, match="forget after"):
        SilenceWatch(None, forget_after=0.0)


@pytest.mark.network
@pytest.mark.timeout(60)
def test_monitor_node_forgets_a_silent_rig_and_says_so(caplog):
    core = MonitorCore(eval_every=3)
    with listening_session() as (mon_s, ep), open_session("peer", connect=[ep]) as pub_s, \
            caplog.at_level(logging.WARNING, logger="hydromon.bus.monitor"):
        stop = threading.Event()
        mon = threading.Thread(target=lambda: run_monitor(mon_s, stop_event=stop, node_name="m5", core=core,
                                                          stale_after_s=None, forget_after_s=0.5), daemon=True)
        mon.start()
        try:
            wait_for(lambda: any(r.ok is not None for r in pub_s.liveliness().get("hydro/monitor/*", timeout=1.0)),
                     30, "the monitor's liveliness token")
            for key, payload in _samples("quiet", 9):
                pub_s.put(key, payload)
            wait_for(lambda: core.counters.accepted == 9, 30, "the 9 samples")
            wait_for(lambda: core.counters.forgotten == 1, 30, "the rig forgotten")
            assert "quiet" not in core.rigs and "quiet" not in core.latest
            assert not [r.ok for r in pub_s.get("hydro/rig/quiet/health", timeout=2.0) if r.ok is not None]
        finally:
            stop.set()
            mon.join(30)
    assert any("rig quiet: forgotten after 0.5 s without a sample" in r.getMessage() for r in caplog.records)


def test_configs_of_rig_ids_that_never_send_a_sample_do_not_keep_a_real_rig_s_config_out():
    core = MonitorCore(eval_every=3, max_rigs=4)
    cfg = orjson.dumps(RigConfig().model_dump())
    core.process([(f"hydro/rig/fake{i}/config", cfg) for i in range(100)])  # a flood of made-up ids
    real = RigConfig(p_s=10e6)
    core.process([("hydro/rig/real/config", orjson.dumps(real.model_dump()))] + _samples("real", 9))
    assert core.rigs["real"].config == real and core.counters.rejected["too-many-rigs"] == 0
    assert len(core.configs) == 4 and core.counters.configs_dropped == 97
    # the configs of rigs that do send samples are never dropped for new ones
    for rig in ("a", "b", "c"):
        core.process([(f"hydro/rig/{rig}/config", cfg)] + _samples(rig, 3))
    core.process([("hydro/rig/late/config", cfg)])
    assert core.counters.rejected["too-many-rigs"] == 1 and set(core.configs) == {"real", "a", "b", "c"}
