"""Bad input over the bus: a ``hydromon monitor`` process fed good and malformed traffic.

A publisher session sends three good rigs (the paper's Table 4 groups 1, 3 and 5, 6 s) with
every malformed kind mixed in: payloads that are not JSON, miss a field, have a wrong type,
NaN/inf, unknown fields, out-of-range values; bad configs; rig ids that are valid zenoh key
chunks but not valid rig ids (65 chars, ``.``, ``~``, a space and ``!``, a non-ASCII letter);
duplicate and out-of-order seq; a rig that sends only junk; and keys outside the contract.
The node must stay up; the good rigs' verdicts must equal those of a clean run (byte for byte;
on the rig with junk on its own sample key, except for a ``bad-input`` status in exactly the
windows holding junk); and every bad message must be counted under its reason, read from the
summary the process prints at exit.

Keys outside the contract (``hydro/rig/<id>/other``, ``hydro/rig/a/b/sample``, ...) never
reach the monitor over the bus: it subscribes only ``<ns>/rig/*/sample`` and
``<ns>/rig/*/config`` and zenoh routes nothing else to it, so they are counted nowhere
(``bad-key`` stays 0); the in-memory tests of ``MonitorCore`` cover that reason.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys

import orjson
import pytest
import zenoh

from helpers import BAD_SAMPLES, assert_clean_but_flagged, health_seqs, sample_with, wait_for  # noqa: F401
from hydromon.bus.session import JSON, listening_session
from hydromon.contract import RigConfig
from hydromon.engine.core import MonitorCore
from hydromon.engine.validate import REJECT_REASONS
from hydromon.store.fleetfile import FleetSpec, RigSpec
from hydromon.store.simfiles import iter_blocks
from plant_sim.degradation import TABLE4_PAPER_GRADES

NS = "hydro"
SECONDS = 6.0
N = int(SECONDS * 100)
SPEC = FleetSpec(rigs=[RigSpec(id=f"table4-g{g}", table4=g) for g in (1, 3, 5)])
VICTIM = "table4-g5"  # gets junk on its own sample key
BLOCK = zenoh.CongestionControl.BLOCK


def _sample(seq, t, row) -> bytes:
    return orjson.dumps({"seq": seq, "t": t, "ug": row[0], "x1": row[1], "x3": row[2], "x4": row[3],
                         "x5": row[4]})


def good_messages() -> list[tuple[str, bytes]]:
    """What the sim node would publish: configs, then the rigs' samples instant by instant."""
    fleet = SPEC.build()
    msgs = [(f"{NS}/rig/{i}/config", orjson.dumps(c.model_dump(mode="json"))) for i, c in zip(SPEC.ids, fleet.configs)]
    for blk in iter_blocks(fleet, N, block=200):
        rows = blk.samples.tolist()
        for j, (seq, t) in enumerate(zip(blk.seq.tolist(), blk.t.tolist())):
            for r, rig in enumerate(SPEC.ids):
                msgs.append((f"{NS}/rig/{rig}/sample", _sample(seq, t, rows[r][j])))
    return msgs


# rig chunks that are valid zenoh keys (and match <ns>/rig/*/sample) but not valid rig ids
BAD_RIG_IDS = ["a" * 65, "bad.id", "bad~id", "bad id!", "r\u00e9sum\u00e9"]
_CFG = RigConfig().model_dump()
BAD_CONFIGS = [
    ("bad-value", orjson.dumps({**_CFG, "A1": -1.0})),
    ("bad-value", orjson.dumps({**_CFG, "sample_rate": 50.0})),
    ("non-finite", orjson.dumps({**_CFG, "p_s": 0.5}).replace(b"0.5", b"NaN")),
    ("wrong-type", orjson.dumps({**_CFG, "p_s": "high"})),
    ("unknown-field", orjson.dumps({**_CFG, "colour": 1.0})),
    ("not-json", b"{"),
]
# valid zenoh keys outside the monitor's subscriptions: zenoh never delivers them to it
OUTSIDE = ["hydro/rig/table4-g1/other", "hydro/rig/a/b/sample", "hydro/rig/table4-g1", "hydro/other",
           "hydro/rig/@x/sample", "other/rig/table4-g1/sample"]


def mixed_messages(good):
    """The good stream with every bad kind mixed in; returns (messages, expected counters,
    samples after which junk went to the victim)."""
    expected = {r: 0 for r in REJECT_REASONS}
    msgs, hist, bad_after = [], {}, []
    n_dup = n_ooo = junk = cfg = ids = outside = 0
    last_index = len(good) - 3 * 20  # the last 0.2 s stay clean: when they are graded, all junk is in
    for i, (key, payload) in enumerate(good):
        msgs.append((key, payload))
        if not key.endswith("/sample") or i >= last_index:
            continue
        rig = key.split("/")[2]
        seq = orjson.loads(payload)["seq"]
        h = hist.setdefault(rig, [])
        h.append(payload)
        if seq < 10:
            continue
        if i % 97 == 0:  # the sample just sent, again
            msgs.append((key, payload))
            n_dup += 1
        elif i % 89 == 0:  # an older sample arriving late (seq >= 5: never 0, which is a restart)
            msgs.append((key, h[-6]))
            n_ooo += 1
        elif rig == VICTIM and seq % 23 == 0:
            reason, bad = BAD_SAMPLES[junk % len(BAD_SAMPLES)]
            junk += 1
            msgs.append((key, bad))
            expected[reason] += 1
            bad_after.append(seq)
        elif i % 61 == 0:
            msgs.append((f"{NS}/rig/{BAD_RIG_IDS[ids % len(BAD_RIG_IDS)]}/sample", sample_with(seq=seq)))
            ids += 1
            expected["bad-rig-id"] += 1
        elif i % 71 == 0:
            reason, bad = BAD_CONFIGS[cfg % len(BAD_CONFIGS)]
            cfg += 1
            msgs.append((f"{NS}/rig/{rig}/config", bad))
            expected[reason] += 1
        elif i % 67 == 0:
            msgs.append((OUTSIDE[outside % len(OUTSIDE)], sample_with(seq=seq)))
            outside += 1
    assert junk >= len(BAD_SAMPLES) and cfg >= len(BAD_CONFIGS) and ids >= len(BAD_RIG_IDS)
    assert outside >= len(OUTSIDE) and n_dup > 3 and n_ooo > 3
    # a rig that only ever sends junk: counted, but gets no row and no health
    for reason, bad in BAD_SAMPLES:
        msgs.insert(len(msgs) // 2, (f"{NS}/rig/junk-rig/sample", bad))
        expected[reason] += 1
    return msgs, expected, n_dup + n_ooo, bad_after


def _by_rig(health, node: str | None = None):
    """Payloads by rig; those of ``node`` with its name and epoch taken out (they end the payload),
    to compare with an in-memory core's, which names no node."""
    out: dict[str, list[bytes]] = {}
    for k, p in health:
        if node is not None:
            h = orjson.loads(p)
            assert h.pop("node") == node and isinstance(h.pop("epoch"), int)
            p = orjson.dumps(h)
        out.setdefault(k.split("/")[2], []).append(p)
    return out


def _alive(proc):
    def check():
        if proc.poll() is not None:
            raise AssertionError(f"the monitor exited with {proc.returncode}")
    return check


_SUMMARY = re.compile(r"hydromon monitor: (\d+) rig\(s\), (\d+) samples, (\d+) health messages; rejected: (.*); "
                      r"dropped seq (\d+), gaps (\d+) \((\d+) samples missing\), restarts (\d+)")


def parse_summary(text: str) -> dict:
    """The counters of the summary line ``hydromon monitor`` prints at exit."""
    m = _SUMMARY.search(text)
    assert m, f"no summary line in the monitor's output:\n{text[-3000:]}"
    rejected = {r: 0 for r in REJECT_REASONS}
    if m.group(4) != "none":
        for part in m.group(4).split(", "):
            reason, count = part.rsplit(" ", 1)
            rejected[reason] = int(count)
    rigs, samples, health, dropped, gaps, missing, restarts = (int(m.group(i)) for i in (1, 2, 3, 5, 6, 7, 8))
    return {"rigs": rigs, "samples": samples, "health": health, "rejected": rejected, "dropped_seq": dropped,
            "gaps": gaps, "missing": missing, "restarts": restarts}


@pytest.mark.network
@pytest.mark.timeout(300)
def test_monitor_process_survives_bad_input_counts_it_and_grades_the_good_rigs(tmp_path):
    good = good_messages()
    clean = _by_rig(MonitorCore(NS).process(good))
    msgs, expected, dropped_seq, bad_after = mixed_messages(good)
    log_path = tmp_path / "monitor.log"
    received: list[tuple[str, bytes]] = []
    # this session listens and the monitor process connects to it, so the two meet as soon as
    # the process opens its session (not at one of zenoh's connect retries, every 4 s at most)
    with open(log_path, "wb") as log, listening_session() as (s, ep):
        # --memory none: the estimators of the clean run's in-memory core (a growing window)
        proc = subprocess.Popen([sys.executable, "-m", "hydromon.cli", "monitor", "--connect", ep, "--node", "bad-in",
                                 "--stale-after", "600", "--memory", "none"],
                                stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                env={**os.environ, "PYTHONUNBUFFERED": "1"})
        try:
            sub = s.declare_subscriber(f"{NS}/rig/*/health", zenoh.handlers.FifoChannel(100_000))
            wait_for(lambda: any(r.ok is not None for r in s.liveliness().get(f"{NS}/monitor/bad-in", timeout=1.0)),
                     180, "the monitor's liveliness token", alive=_alive(proc))
            pubs: dict[str, zenoh.Publisher] = {}
            for key, payload in msgs:  # one session, one link: zenoh keeps this order
                pub = pubs.get(key)
                if pub is None:
                    pub = pubs[key] = s.declare_publisher(key, encoding=JSON, congestion_control=BLOCK)
                pub.put(payload)

            def drain() -> bool:
                while (m := sub.try_recv()) is not None:
                    received.append((str(m.key_expr), m.payload.to_bytes()))
                got = _by_rig(received, node="bad-in")
                return all(r in got and orjson.loads(got[r][-1])["seq"] == health_seqs(r, N)[-1]
                           for r in SPEC.ids)

            wait_for(drain, 180, "the last verdict of every good rig", alive=_alive(proc))
            assert proc.poll() is None  # still up after all of it
            assert any(r.ok is not None for r in s.liveliness().get(f"{NS}/monitor/bad-in", timeout=5.0))
            for pub in pubs.values():
                pub.undeclare()
            proc.send_signal(signal.SIGINT)
            assert proc.wait(30) == 0, log_path.read_text()
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(30)
    summary = parse_summary(log_path.read_text())
    assert summary["rejected"] == expected, log_path.read_text()[-3000:]
    assert summary["rejected"]["bad-key"] == 0  # keys outside the contract never reach the node
    assert summary["dropped_seq"] == dropped_seq
    assert (summary["rigs"], summary["samples"], summary["health"]) == \
        (3, 3 * N, sum(len(health_seqs(r, N)) for r in SPEC.ids))
    assert (summary["gaps"], summary["missing"], summary["restarts"]) == (0, 0, 0)

    got = _by_rig(received, node="bad-in")
    assert sorted(got) == sorted(SPEC.ids)  # no health for the junk-only rig nor the bad ids
    for rig in SPEC.ids:
        if rig != VICTIM:
            assert got[rig] == clean[rig]  # every verdict, byte for byte
    # the victim: the clean verdicts, flagged bad-input in exactly the windows holding junk
    assert_clean_but_flagged(VICTIM, got[VICTIM], clean[VICTIM], bad_after)
    # the final grades: the clean run's, which are the rigs' true grades
    for rig in SPEC.ids:
        final = orjson.loads(got[rig][-1])
        assert final["grade"] == orjson.loads(clean[rig][-1])["grade"] == TABLE4_PAPER_GRADES[int(rig[-1])]
        assert final["status"] == "ok"
