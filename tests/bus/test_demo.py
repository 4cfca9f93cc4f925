"""``hydromon demo`` end to end: a subprocess, twice in a row, writes a recording that holds
the samples, configs and verdicts, and ends with every rig at its true grade."""

from __future__ import annotations

import os
import subprocess
import sys
from collections import Counter

import pytest

from helpers import health_seqs
from hydromon.contract import Health
from hydromon.report.demo import render_plain
from hydromon.store.fleetfile import RigSpec, default_fleet, true_grade
from hydromon.store.mcap_read import read_recording
from hydromon.store.replay import replay_direct


def test_true_grades_and_plain_table():
    spec = default_fleet()
    truth = {r.id: true_grade(r) for r in spec.rigs}
    assert truth == {"table4-g1": "sub-health", "table4-g2": "health", "table4-g3": "fault",
                     "table4-g4": "average", "table4-g5": "deterioration"}
    assert true_grade(RigSpec(id="x", severity=0.5)) == "average"
    assert true_grade(RigSpec(id="x", table4=1, params={"f_c": 30.0})) is None
    h = {"t": 1.5, "grade": "fault", "confidence": 0.6, "status": "ok",
         "params": {"f_c": 96.8, "B_fv": 6740.0}}
    text = render_plain(["table4-g3", "table4-g1"], {"table4-g3": h}, truth).splitlines()
    assert text[0].split() == ["rig", "grade", "conf", "status", "K_sv", "f_c", "B_fv", "C_ip",
                               "t", "[s]", "true"]
    assert text[1].split() == ["table4-g3", "fault", "0.60", "ok", "-", "96.8", "6740", "-", "1.5", "fault"]
    assert text[2].split() == ["table4-g1", "-", "-", "waiting", "-", "-", "-", "-", "-", "sub-health"]


@pytest.mark.network
@pytest.mark.timeout(120)
def test_demo_runs_twice_in_a_row_and_records(tmp_path):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    for run in (1, 2):
        proc = subprocess.run([sys.executable, "-m", "hydromon.cli", "demo", "--duration", "8", "--rate", "5",
                               "--out", str(tmp_path)], capture_output=True, text=True, timeout=100, env=env)
        assert proc.returncode == 0, proc.stderr
        files = sorted(tmp_path.glob("demo-*.mcap"))
        assert len(files) == run
        assert f"recording: {files[-1]}" in proc.stdout
        assert "5/5 rigs at their true grade" in proc.stdout, proc.stdout
        assert "rejected 0, gaps 0, dropped seq 0" in proc.stderr
    kinds = Counter()
    last, recorded = {}, {}
    for key, payload, _, _ in read_recording(files[-1]):
        leaf = key.rsplit("/", 1)[1]
        kinds[leaf] += 1
        if leaf == "health":
            last[key.split("/")[2]] = Health.model_validate_json(payload)
            recorded.setdefault(key, []).append(payload)
    # live equals replay: the recording, graded again in-process, gives the live verdicts
    replayed = {}
    for key, payload in replay_direct(files[-1])[0]:
        replayed.setdefault(key, []).append(payload)
    assert replayed == recorded
    assert kinds["config"] == 5 and kinds["sample"] >= 5 * 500
    # every verdict the monitor made is in the recording: one per 10 samples of each rig
    assert kinds["sample"] % 5 == 0  # the sim sends every rig's sample of an instant together
    n = kinds["sample"] // 5
    assert kinds["health"] == sum(len(health_seqs(r.id, n)) for r in default_fleet().rigs)
    assert sorted(last) == [f"table4-g{g}" for g in range(1, 6)]
    truth = {r.id: true_grade(r) for r in default_fleet().rigs}
    assert {r: h.grade for r, h in last.items()} == truth
