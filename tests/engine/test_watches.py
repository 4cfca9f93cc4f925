"""The monitor node's watchers: the rate-limited rejection log."""

from __future__ import annotations

from hydromon.engine.watches import RateLimitedLog


def test_rejection_log_is_rate_limited_per_reason(caplog):
    now = [0.0]
    rl = RateLimitedLog(interval=5.0, clock=lambda: now[0])
    with caplog.at_level("WARNING", logger="hydromon.bus.monitor"):
        for i in range(100):
            now[0] = i * 0.1  # 10 s of rejections
            rl("not-json", "hydro/rig/a/sample", "bad")
            if i % 10 == 0:
                rl("bad-key", "x/y", "nope")
    lines = [r.getMessage() for r in caplog.records]
    assert [ln.split()[1] for ln in lines] == ["not-json", "bad-key", "not-json", "bad-key"]
    assert lines[2].endswith("(+49 more since the last report)")  # 0.1 .. 4.9 s suppressed
    assert lines[3].endswith("(+4 more since the last report)")


def test_rejection_log_reports_a_last_burst_without_a_further_rejection(caplog):
    now = [0.0]
    rl = RateLimitedLog(interval=5.0, clock=lambda: now[0])
    with caplog.at_level("WARNING", logger="hydromon.bus.monitor"):
        for i in range(30):  # 3 s of rejections, then none
            now[0] = i * 0.1
            rl("not-json", "hydro/rig/a/sample", "bad")
        rl("bad-key", "x/y", "nope")
        now[0] = 4.0
        rl.flush()  # not due yet
        assert len(caplog.records) == 2
        now[0] = 5.0
        rl.flush()
        assert caplog.records[-1].getMessage() == "rejected not-json: 29 more since the last report"
        rl.flush(final=True)  # nothing more suppressed: nothing to say
        assert len(caplog.records) == 3
        rl("bad-key", "x/y", "nope")
        rl.flush(final=True)  # the node stopping: reported whether due or not
    assert caplog.records[-1].getMessage() == "rejected bad-key: 1 more since the last report"


def test_rig_warnings_are_rate_limited_per_rig_and_kind(caplog):
    from hydromon.engine.watches import RigWarningLog

    now = [0.0]
    wl = RigWarningLog(interval=5.0, clock=lambda: now[0])
    with caplog.at_level("WARNING", logger="hydromon.bus.monitor"):
        for i in range(120):  # a rig whose config flips every message for 12 s
            now[0] = i * 0.1
            wl("flip", f"config changed (F_L): its estimates restart ({i})")
            wl("flip", "not graded: no ranges were made for it")
        wl("calm", "config changed (p_s): its estimates restart")  # another rig is told at once
        wl.flush(final=True)
    lines = [r.getMessage() for r in caplog.records]
    assert lines[:2] == ["rig flip: config changed (F_L): its estimates restart (0)",
                         "rig flip: not graded: no ranges were made for it"]
    assert lines[2] == ("rig flip: config changed (F_L): its estimates restart (50) (+49 more like it since the "
                        "last report)")
    assert "rig calm: config changed (p_s): its estimates restart" in lines
    assert lines[-2:] == ["rig flip: 19 more warnings 'config changed...' since the last report",
                          "rig flip: 19 more warnings 'not graded...' since the last report"]
    assert len(lines) == 9  # 240 warnings of one rig in 12 s: three lines a kind


def test_rig_warnings_of_one_kind_that_carry_numbers_are_one_kind_and_quiet_kinds_are_forgotten(caplog):
    from hydromon.engine.watches import RigWarningLog

    now = [0.0]
    wl = RigWarningLog(interval=5.0, clock=lambda: now[0])
    with caplog.at_level("WARNING", logger="hydromon.bus.monitor"):
        for i in range(200):
            now[0] = i * 0.01
            wl("r", f"seq went back from {1000 + i} to {i}: two publishers under one rig id?")
    assert len(caplog.records) == 1
    now[0] = 20.0
    wl.flush()
    said = caplog.records[-1].getMessage()
    assert said == "rig r: 199 more warnings 'seq went back from # to #...' since the last report", said
    now[0] = 30.0
    wl.flush()
    assert wl._throttle._last == {} and wl._throttle._suppressed == {}
