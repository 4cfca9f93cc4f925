"""Monitor node: edge validation and sequence handling of MonitorCore (in memory), and the
node on a real zenoh session on loopback (network)."""

from __future__ import annotations

import orjson
import pytest

from helpers import BAD_SAMPLES, assert_clean_but_flagged, by_rig, fleet_messages, health_seqs, sample_with
from hydromon.contract import GRADES, PARAM_NAMES, Health, RigConfig, health_key
from hydromon.engine.core import MonitorCore
from hydromon.engine.samples import sample_payload
from hydromon.engine.validate import REJECT_REASONS
from hydromon.store.fleetfile import FleetSpec, default_fleet
from monitor.evaluations import eval_phase
from monitor.ranges import Ranges
from plant_sim.degradation import TABLE4_PAPER_GRADES

NS = "hydro"
SPEC = default_fleet()
CLEAN = fleet_messages(SPEC, 6.0)


def run_core(msgs, chunk=None, **kw):
    core = MonitorCore(NS, **kw)
    if chunk is None:
        return core, core.process(msgs)
    out = []
    for i in range(0, len(msgs), chunk):
        out += core.process(msgs[i:i + chunk])
    return core, out


@pytest.fixture(scope="module")
def clean_run():
    return run_core(CLEAN)


def test_clean_run_gives_valid_health_and_true_grades(clean_run):
    core, health = clean_run
    c = core.counters
    assert c.accepted == 600 * 5 and c.rejected_total == 0 and c.dropped_seq == 0 and c.gaps == 0
    rigs = by_rig(health)
    assert sorted(rigs) == sorted(SPEC.ids)
    for rig, payloads in rigs.items():
        hs = [Health.model_validate_json(p) for p in payloads]
        assert [h.seq for h in hs] == health_seqs(rig, 600)  # one every 10 samples, staggered by rig
        assert all(h.status in ("converging", "ok") for h in hs)
        for h in hs:
            assert (h.level is None) == (h.grade == "unknown")
            if h.level is not None:
                assert GRADES[h.level] == h.grade
        last = hs[-1]
        assert last.status == "ok"
        assert last.grade == TABLE4_PAPER_GRADES[int(rig[-1])]
        assert core.latest[rig] == payloads[-1]
        assert set(last.param_grades) == set(core.fleet.graded(core.rigs[rig].row)) == set(Ranges.default().params)
        assert last.ranges == "default"


def test_batching_does_not_change_health():
    _, whole = run_core(CLEAN[:2000])
    assert len(whole) > 20
    for chunk in (1, 7, 333):
        assert run_core(CLEAN[:2000], chunk=chunk)[1] == whole


BAD_KEYS = [
    ("bad-rig-id", "hydro/rig/bad.id/sample"),
    ("bad-rig-id", "hydro/rig/" + "a" * 65 + "/sample"),
    ("bad-rig-id", "hydro/rig/bad id/config"),
    ("bad-key", "hydro/rig/table4-g1/other"),
    ("bad-key", "other/rig/table4-g1/sample"),
    ("bad-key", "hydro/rig/a/b/sample"),
    ("bad-key", "hydro/rig/table4-g1"),
]
BAD_CONFIGS = [
    ("bad-value", orjson.dumps({**RigConfig().model_dump(), "A1": -1.0})),
    ("bad-value", orjson.dumps({**RigConfig().model_dump(), "sample_rate": 50.0})),
    ("non-finite", orjson.dumps({**RigConfig().model_dump(), "p_s": 0.5}).replace(b"0.5", b"NaN")),
    ("wrong-type", orjson.dumps({**RigConfig().model_dump(), "p_s": "high"})),
    ("unknown-field", orjson.dumps({**RigConfig().model_dump(), "colour": 1.0})),
    ("not-json", b"{"),
]


def test_every_malformed_kind_is_counted_and_good_rigs_are_unaffected(clean_run):
    _, clean = clean_run
    victim = "table4-g5"
    expected = {r: 0 for r in REJECT_REASONS}
    msgs, n_dup, n_ooo = [], 0, 0
    bad_at: dict[str, list] = {}  # rig -> seqs after which a message on its keys was rejected
    last_payload: dict[str, list] = {}
    junk_i = 0
    for i, (key, payload) in enumerate(CLEAN):
        msgs.append((key, payload))
        rig = key.split("/")[2]
        hist = last_payload.setdefault(rig, [])
        hist.append(payload)
        if i < 10 or not key.endswith("/sample"):
            continue
        if i % 97 == 0:  # a duplicate of the sample just sent
            msgs.append((key, payload))
            n_dup += 1
        elif i % 89 == 0 and len(hist) > 5:  # an old sample arriving late
            msgs.append((key, hist[-5]))
            n_ooo += 1
        elif rig == victim and len(hist) % 23 == 0:  # a malformed payload on the victim's key
            reason, bad = BAD_SAMPLES[junk_i % len(BAD_SAMPLES)]
            junk_i += 1
            msgs.append((key, bad))
            expected[reason] += 1
            bad_at.setdefault(rig, []).append(orjson.loads(payload)["seq"])
        elif i % 61 == 0:
            reason, bad_key = BAD_KEYS[i % len(BAD_KEYS)]
            msgs.append((bad_key, sample_payload(3, 0.03, [0.0, 0.0, 1e6, 1e6, 0.0])))
            expected[reason] += 1
        elif i % 71 == 0:
            reason, bad = BAD_CONFIGS[i % len(BAD_CONFIGS)]
            msgs.append((f"hydro/rig/{rig}/config", bad))
            expected[reason] += 1
            # a rejected config flags the rig's next health too (it stays on its constants)
            bad_at.setdefault(rig, []).append(orjson.loads(payload)["seq"])
    assert junk_i >= len(BAD_SAMPLES)  # every kind was injected at least once
    # a rig that only ever sends junk gets no row and no health
    for reason, bad in BAD_SAMPLES:
        msgs.insert(len(msgs) // 2, ("hydro/rig/junk-rig/sample", bad))
        expected[reason] += 1
    msgs.append((health_key("table4-g1"), b"{}"))  # health is our output kind: ignored

    core, health = run_core(msgs, chunk=250)
    c = core.counters
    assert c.rejected == expected
    assert (c.duplicate, c.out_of_order, c.gaps, c.restarts, c.ignored) == (n_dup, n_ooo, 0, 0, 1)
    assert c.accepted == 3000 and "junk-rig" not in core.rigs and sorted(core.rigs) == sorted(SPEC.ids)
    got, want = by_rig(health), by_rig(clean)
    assert victim in bad_at and len(bad_at) > 1  # junk samples on the victim, bad configs on others
    for rig in SPEC.ids:  # the same verdicts, flagged bad-input in exactly the windows after a rejected message
        assert_clean_but_flagged(rig, got[rig], want[rig], bad_at.get(rig, []))


def test_a_gap_restarts_the_filters_and_marks_health_stale(clean_run):
    _, clean = clean_run
    rig = "table4-g2"
    lost = set(range(400, 415))
    msgs = [(k, p) for k, p in CLEAN
            if not (k == f"hydro/rig/{rig}/sample" and orjson.loads(p)["seq"] in lost)]
    core, health = run_core(msgs)
    assert (core.counters.gaps, core.counters.missing, core.counters.accepted) == (1, 15, 3000 - 15)
    got, want = by_rig(health), by_rig(clean)
    for other in SPEC.ids:
        if other != rig:
            assert got[other] == want[other]
    hs = [Health.model_validate_json(p) for p in got[rig]]
    # windows count the rig's samples (staggered by its phase), so after the gap they move by
    # the 15 lost samples; the first window after the gap holds fewer than 10 samples after it
    # -> stale; the next one is ok
    ph = eval_phase(rig, 10)
    before = health_seqs(rig, 400)
    first = next(e for e in range(415, 430) if (e - 15 + 1 + ph) % 10 == 0)
    status = {h.seq: h.status for h in hs}
    assert status[before[-1]] == "ok" and not any(before[-1] < q < first for q in status)
    assert status[first] == "stale" and status[first + 10] == "ok"
    assert [h.seq for h in hs if h.status == "stale"] == [first]
    assert hs[-1].grade == TABLE4_PAPER_GRADES[2]


def test_seq_back_to_zero_is_a_restart_and_gives_the_clean_verdicts_again(clean_run):
    _, clean = clean_run
    first = CLEAN[:5 + 5 * 300]  # configs + 3 s
    core, health = run_core(first + CLEAN[5:])
    assert core.counters.restarts == 5 and core.counters.dropped_seq == 0
    dup0 = CLEAN[:6] + [CLEAN[5]] + CLEAN[6:100]  # seq 0 twice in a row: a duplicate, not a restart
    assert run_core(dup0)[0].counters.duplicate == 1 and run_core(dup0)[0].counters.restarts == 0
    got, want = by_rig(health), by_rig(clean)
    for rig in SPEC.ids:
        assert got[rig][len(health_seqs(rig, 300)):] == want[rig]  # after the verdicts before the restart


def test_a_restart_whose_seq_0_was_lost_is_a_restart_not_a_run_of_drops(clean_run):
    # fault injection: a sim killed and restarted as a peer; the monitor reconnected after the
    # new run's first samples, so it never saw seq 0. Every sample was dropped as out of order
    # until the new seq passed the old run's last (no health for that long, nothing logged), and
    # then the old run's estimates carried on into the new run
    _, clean = clean_run
    warnings = []
    first = CLEAN[:5 + 5 * 300]  # configs + 3 s
    lost = 20                    # the new run's first 20 samples never arrive
    core, health = run_core(first + CLEAN[5 + 5 * lost:], chunk=250,
                            on_warning=lambda rig, msg: warnings.append((rig, msg)))
    c = core.counters
    assert c.restarts == 5
    from hydromon.contract import RESTART_RUN

    assert c.out_of_order == 5 * (RESTART_RUN - 1) and c.gaps == 0
    assert sorted(rig for rig, m in warnings if "taken as a restart" in m) == sorted(SPEC.ids)
    got, want = by_rig(health), by_rig(clean)
    back = lost + RESTART_RUN - 1  # the sample the new run restarts at
    for rig in SPEC.ids:
        hs = [orjson.loads(p) for p in got[rig]]
        after = hs[len(health_seqs(rig, 300)):]
        assert after[0]["seq"] < back + 10 and after[0]["status"] == "converging"  # graded again at once
        assert [h["seq"] for h in after] == sorted(h["seq"] for h in after) and after[-1]["seq"] >= 590
        assert after[-1]["status"] == "ok" and after[-1]["grade"] == orjson.loads(want[rig][-1])["grade"]


def test_a_second_publisher_under_one_rig_id_is_warned_of_and_restarts_nothing(clean_run):
    # two sims publishing the same rig ids: the second one's samples (below the first one's
    # seq, interleaved with them) are dropped and counted, once logged per rig; they make no run
    _, clean = clean_run
    warnings = []
    samples = CLEAN[5:]
    msgs = CLEAN[:5 + 5 * 300]
    for i in range(5 * 300, len(samples), 5):
        msgs += samples[i:i + 5] + samples[i - 5 * 299:i - 5 * 298]  # the other one at seq 1, 2, ...
    core, health = run_core(msgs, chunk=250, on_warning=lambda rig, msg: warnings.append((rig, msg)))
    assert core.counters.restarts == 0 and core.counters.out_of_order == 5 * 300
    assert sorted(rig for rig, _ in warnings) == sorted(SPEC.ids)
    assert all("two publishers" in msg for _, msg in warnings)
    assert by_rig(health) == by_rig(clean)


def test_a_rig_that_goes_silent_has_its_latest_health_re_sent_stale_once():
    # fault injection: a sim killed mid-run. Health comes from samples, so its rigs kept their
    # last `ok` for good, on the health query too (the dashboard of a dead rig said ok)
    from hydromon.engine.watches import SilenceWatch

    core, watch = MonitorCore(NS), SilenceWatch(2.0)
    core.process(CLEAN[:5 + 5 * 400])
    assert watch.check(core, 0.0) == [] and watch.check(core, 1.9) == []
    before = dict(core.latest)
    stale = watch.check(core, 2.1)
    assert sorted(k for k, _ in stale) == sorted(health_key(r) for r in SPEC.ids)
    for key, payload in stale:  # the last verdict, grade and numbers, now marked stale
        rig = key.split("/")[2]
        assert orjson.loads(payload) == {**orjson.loads(before[rig]), "status": "stale"}
        assert core.latest[rig] == payload  # what the health query answers
    assert watch.check(core, 10.0) == []  # once per silence
    core.process(CLEAN[5 + 5 * 400:5 + 5 * 420])  # the rigs speak again
    assert watch.check(core, 10.1) == [] and watch.check(core, 11.0) == []
    assert all(orjson.loads(p)["status"] == "ok" for p in core.latest.values())
    assert len(watch.check(core, 12.2)) == 5  # and fall silent again


def test_a_rig_whose_every_sample_is_refused_says_bad_input_not_stale():
    """Its messages keep coming, so it is not silent: what it sends is refused (a sensor beyond
    the contract's limits), and the health and its event say so."""
    from hydromon.engine.watches import SilenceWatch

    core, watch = MonitorCore(NS), SilenceWatch(2.0)
    core.process(CLEAN[:5 + 5 * 400])
    core.take_events()
    watch.check(core, 0.0)
    rig = SPEC.ids[0]
    bad = [(health_key(rig).replace("/health", "/sample"), sample_with(seq=400 + k, x3=2e9)) for k in range(300)]
    core.process(bad)
    assert core.counters.rejected["bad-value"] == 300
    resent = dict(watch.check(core, 2.1))
    assert orjson.loads(resent[health_key(rig)])["status"] == "bad-input"
    assert {orjson.loads(p)["status"] for k, p in resent.items() if k != health_key(rig)} == {"stale"}
    events = [orjson.loads(p) for k, p in core.take_events() if f"/{rig}/" in k]
    assert [(e["kind"], e["to"]) for e in events] == [("status", "bad-input")], events
    assert watch.check(core, 10.0) == []
    # a link that dies mid-message leaves one cut-off message, then silence: that rig is stale
    core, watch = MonitorCore(NS), SilenceWatch(2.0)
    core.process(CLEAN[:5 + 5 * 400])
    watch.check(core, 0.0)
    core.process([(health_key(rig).replace("/health", "/sample"), b'{"seq": 400, "t": 4.0, "ug": 0.1')])
    resent = dict(watch.check(core, 2.1))
    assert {orjson.loads(p)["status"] for p in resent.values()} == {"stale"} and len(resent) == 5


def test_a_changed_config_restarts_the_rig_and_equal_configs_do_nothing():
    rig = "table4-g1"
    changed = RigConfig(p_s=13e6)
    msgs = CLEAN[:1005] + [(f"hydro/rig/{rig}/config", orjson.dumps(RigConfig().model_dump()))] + CLEAN[1005:2005]
    core, health = run_core(msgs)
    assert core.counters.config_changes == 0 and health == run_core(CLEAN[:2005])[1]
    msgs = CLEAN[:1005] + [(f"hydro/rig/{rig}/config", orjson.dumps(changed.model_dump()))] + CLEAN[1005:2005]
    warnings = []
    core, health = run_core(msgs, on_warning=lambda r, m: warnings.append((r, m)))
    assert core.counters.config_changes == 1 and core.configs[rig] == changed
    # said once, naming what changed (the estimates restart: the log must say why)
    assert [w for w in warnings if "config changed" in w[1]] == [
        (rig, "config changed (p_s): its estimates restart with the new constants (a grade again after about 3 s "
              "of samples)")]
    seqs = [orjson.loads(p)["seq"] for k, p in health if k == health_key(rig)]
    # 200 samples before the change, then the count restarts at the change (sample 200)
    before = health_seqs(rig, 200)
    assert seqs[:len(before) + 1] == before + [health_seqs(rig, 400, first=200)[0]]
    assert [orjson.loads(p)["seq"] for k, p in health if k == health_key("table4-g2")] == health_seqs("table4-g2", 400)


def test_one_absurd_reading_is_rejected_and_the_rig_keeps_its_estimates(clean_run):
    # a glitch of 1e300 Pa once left the rig's estimates at -1e295 for the rest of the run
    _, clean = clean_run
    rig = "table4-g2"
    key = f"hydro/rig/{rig}/sample"
    msgs = [(k, sample_with(**{**orjson.loads(p), "x3": 1e300}) if k == key and orjson.loads(p)["seq"] == 200 else p)
            for k, p in CLEAN]
    core, health = run_core(msgs)
    assert core.counters.rejected["bad-value"] == 1 and core.counters.gaps == 1
    got, want = by_rig(health), by_rig(clean)
    last, ref = orjson.loads(got[rig][-1]), orjson.loads(want[rig][-1])
    assert last["status"] == "ok" and last["grade"] == ref["grade"] == TABLE4_PAPER_GRADES[2]
    # relative only (the parameters span 1e-13 .. 1e6): measured worst 7.7e-4 (C_ep; f_c 4.7e-4,
    # the rest below 6e-5), so 2e-3 is that times ~2.6
    assert set(last["params"]) == set(ref["params"]) == set(PARAM_NAMES)
    for name, v in ref["params"].items():
        assert abs(last["params"][name] - v) <= 2e-3 * abs(v), (name, last["params"][name], v)
    assert any(orjson.loads(p)["status"] == "bad-input" for p in got[rig])


def test_a_monitor_in_another_namespace_publishes_there_and_takes_nothing_from_hydro():
    spec = FleetSpec(rigs=SPEC.rigs[:2])
    site2 = fleet_messages(spec, 2.0, ns="site2")
    hydro = fleet_messages(spec, 2.0, ns="hydro")
    intruder = [("hydro/rig/intruder/config", orjson.dumps(RigConfig().model_dump(mode="json")))] + \
        [("hydro/rig/intruder/sample", sample_payload(k, k * 0.01, [0.1, 0.01, 5e6, 6e6, 1e-5])) for k in range(50)]
    mixed = [m for pair in zip(hydro, site2) for m in pair] + intruder  # hydro's copy of each message first
    core = MonitorCore("site2")
    health = core.process(mixed)
    assert {k for k, _ in health} == {f"site2/rig/{i}/health" for i in spec.ids}
    assert sorted(core.rigs) == sorted(core.latest) == sorted(spec.ids)
    c = core.counters
    assert c.accepted == 2 * 200 and c.configs == 2 and c.dropped_seq == 0 and c.ignored == 0
    assert c.rejected_total == c.rejected["bad-key"] == len(hydro) + len(intruder)  # not under site2/rig/
    # the same verdicts as the default namespace gives the same rigs
    ref = MonitorCore().process(hydro)
    assert [(k.replace("site2/", "hydro/", 1), p) for k, p in health] == ref


def test_health_payloads_hold_only_finite_numbers():
    # early verdicts have equations without rows: infinite standard errors are left out
    core, health = run_core(CLEAN[:5 + 5 * 40])
    first = orjson.loads(health[0][1])
    assert first["status"] == "converging" and first["level"] is None and first["grade"] == "unknown"
    for _, p in health:
        Health.model_validate_json(p)  # allow_inf_nan=False: would fail on any NaN/inf
    assert any(len(orjson.loads(p)["std_errors"]) < len(PARAM_NAMES) for _, p in health)




# -- on a real zenoh session on loopback --------------------------------------------------------


def test_the_exit_summary_names_rigs_whose_x1_empties_a_chamber():
    from hydromon.cli.commands.monitor import x1_clamped_line

    core = MonitorCore(NS)
    # rig "bad": chamber 1 empties at x1 = -V10 / A1 = -0.05 m, and its x1 reads -0.06 m
    msgs = [(f"{NS}/rig/bad/config", orjson.dumps(RigConfig(V10=0.0004).model_dump(mode="json")))]
    for k in range(30):
        for rig, x1 in (("bad", -0.06), ("good", 0.01)):
            msgs.append((f"{NS}/rig/{rig}/sample", sample_payload(k, k * 0.01, [2.0, x1, 6e6, 4e6, 1e-5])))
    core.process(msgs)
    assert core.counters.accepted == 60
    assert x1_clamped_line(core).endswith(": bad 28 sample(s)")  # the gate holds the last two
    assert x1_clamped_line(MonitorCore(NS)) is None


def test_a_rig_whose_x1_empties_a_chamber_is_warned_of_once_while_running():
    from hydromon.engine.core import X1_CLAMPED_WARNING

    warnings, changes, others = [], [], []
    # (config changes are warned of too: counted apart; so is the rig left ungraded, its constants
    # not the reference rig's)
    core = MonitorCore(NS, on_warning=lambda rig, msg: (changes if msg.startswith("config changed") else
                                                        warnings if msg == X1_CLAMPED_WARNING else others)
                       .append((rig, msg)))
    cfg = lambda v10: (f"{NS}/rig/bad/config", orjson.dumps(RigConfig(V10=v10).model_dump(mode="json")))  # noqa: E731

    def samples(k0, n):
        return [(f"{NS}/rig/{rig}/sample", sample_payload(k, k * 0.01, [2.0, x1, 6e6, 4e6, 1e-5]))
                for k in range(k0, k0 + n) for rig, x1 in (("bad", -0.06), ("good", 0.01))]

    core.process([cfg(0.0004)] + samples(0, 10))   # chamber 1 empties at x1 = -0.05 m
    assert warnings == [("bad", X1_CLAMPED_WARNING)]
    core.process(samples(10, 20))                     # still clamping: no second warning
    assert len(warnings) == 1
    core.process([cfg(0.0004 * 2)] + samples(30, 10))  # corrected constants: V10 / A1 = 0.1 m
    assert len(warnings) == 1 and core.fleet.x1_clamped(core.rigs["bad"].row) == 0
    core.process([cfg(0.0004)] + samples(40, 10))     # wrong again: warned again
    assert warnings == [("bad", X1_CLAMPED_WARNING)] * 2
    core.process([cfg(0.0003)] + samples(50, 10))     # another wrong one: its own warning
    assert warnings == [("bad", X1_CLAMPED_WARNING)] * 3
    core.process(samples(0, 10))                      # the rig restarted (seq 0): afresh
    assert warnings == [("bad", X1_CLAMPED_WARNING)] * 4
    assert [r for r, _ in changes] == ["bad"] * 3  # the three changes after the first config


def test_a_monitor_holds_at_most_max_rigs_and_says_so():
    """Bogus but valid rig ids cannot grow the monitor without bound (20,000 of them would add about
    100 MB). Beyond max_rigs a new id's samples and configs are rejected (too-many-rigs); known rigs
    carry on."""
    rejected = []
    core = MonitorCore(NS, max_rigs=2, on_reject=lambda r, k, d: rejected.append((r, k, d)))
    cfg = orjson.dumps(RigConfig().model_dump(mode="json"))
    msgs = []
    for k in range(30):
        for rig in ("a", "b", "c"):
            msgs.append((f"{NS}/rig/{rig}/sample", sample_with(seq=k, t=k * 0.01)))
    msgs.append((f"{NS}/rig/d/config", cfg))
    health = core.process(msgs)
    assert sorted(core.rigs) == ["a", "b"] and "d" not in core.configs
    assert {key.split("/")[2] for key, _ in health} == {"a", "b"}
    assert core.counters.rejected["too-many-rigs"] == 31
    assert {k.split("/")[2] for _, k, _ in rejected} == {"c", "d"}
    assert "its limit of 2 rigs (--max-rigs)" in rejected[0][2]
    with pytest.raises(ValueError, match="max_rigs"):
        MonitorCore(NS, max_rigs=0)


def test_a_rejected_config_of_a_graded_rig_makes_its_next_health_bad_input():
    """A config at another sample rate is rejected, and not only in a rate-limited log line: the
    rig's next health says bad-input (still graded on the constants it had), the one after it ok
    again."""
    core, health = run_core(CLEAN[:5 + 5 * 400])
    rig = "table4-g1"
    assert orjson.loads(core.latest[rig])["status"] == "ok"
    bad = orjson.dumps(RigConfig(sample_rate=200.0).model_dump(mode="json"))
    out = core.process([(f"{NS}/rig/{rig}/config", bad)] + CLEAN[5 + 5 * 400:5 + 5 * 440])
    statuses = [orjson.loads(p)["status"] for k, p in out if k == health_key(rig)]
    assert statuses[0] == "bad-input" and set(statuses[1:]) == {"ok"}, statuses
    assert orjson.loads([p for k, p in out if k == health_key(rig)][0])["grade"] != "unknown"
    assert core.counters.rejected["bad-value"] == 1 and core.counters.config_changes == 0


