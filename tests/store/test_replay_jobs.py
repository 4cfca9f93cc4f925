"""A direct replay split over processes gives the single-process replay's health, byte for byte and in
order, with the same counters, on a recording of samples and frames mixed with bad input."""

from __future__ import annotations

import io
import os

import numpy as np
import pytest

from hydromon.engine.core import MonitorCore
from hydromon.store.fleetfile import default_fleet, spread_fleet
from hydromon.store.mcap_read import read_recording
from hydromon.store.mcap_write import RecordingWriter
from hydromon.store.replay import replay_direct
from hydromon.store.replay_jobs import replay_direct_jobs, shard_rigs
from hydromon.store.simfiles import write_mcap


def _messages(spec, seconds, frame=None):
    buf = io.BytesIO()
    write_mcap(spec, seconds, buf, frame=frame)
    return [(k, p, t) for k, p, t, _ in read_recording(io.BytesIO(buf.getvalue()))]


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    """Five rigs sending samples, three sending frames of 10, and what goes wrong on a bus."""
    samples = _messages(default_fleet(), 4.0)
    frames = _messages(spread_fleet(3, profile="paper-var", noise="realistic"), 4.0, frame=10)
    msgs = sorted(samples + frames, key=lambda m: m[2])
    rng = np.random.default_rng(7)
    out = []
    for i, (key, payload, t) in enumerate(msgs):
        r = rng.random()
        if r < 0.01:
            continue  # lost: a gap
        out.append((key, payload, t))
        if r > 0.995:
            out.append((key, payload, t))  # repeated
        if i % 97 == 0:
            out.append((key, b'{"seq": "junk"', t))  # malformed, on a rig's own key
        if i % 401 == 0:
            out.append(("hydro/status", b"{}", t))  # a key of no rig
            out.append(("elsewhere/rig/x/sample", payload, t))  # another namespace
            out.append((key.rsplit("/", 1)[0] + "/health", b"{}", t))  # a monitor's output, recorded
    path = tmp_path_factory.mktemp("jobs") / "mixed.mcap"
    with open(path, "wb") as f, RecordingWriter(f) as w:
        for key, payload, t in out:
            w.write(key, payload, t, t)
    return path


@pytest.mark.parametrize("window", [{}, {"start": 1.0, "duration": 2.0}, {"keys": ["hydro/rig/table4-$*/**"]}])
def test_two_and_three_jobs_give_the_single_process_replay(mixed, window):
    health, core = replay_direct(mixed, **window)
    if not window:  # the recording has what it should
        c = core.counters
        assert len(core.rigs) == 8 and len(health) > 100
        assert c.rejected_total > 0 and c.dropped_seq > 0 and c.gaps > 0 and c.ignored > 0
    for jobs in (2, 3):
        got, res = replay_direct_jobs(mixed, jobs=jobs, **window)
        assert got == health
        assert res.counters.as_dict() == core.counters.as_dict()
        assert res.rigs == set(core.rigs) and res.latest == core.latest


def test_an_open_file_is_read_by_its_path_in_each_worker(mixed):
    want = replay_direct(mixed)[0]
    with open(mixed, "rb") as f:
        assert replay_direct_jobs(f, jobs=2)[0] == want
    got, core = replay_direct_jobs(io.BytesIO(mixed.read_bytes()), jobs=2)
    assert got == want and not isinstance(core, MonitorCore)


def test_one_job_runs_here_and_rigs_are_dealt_round_robin(mixed):
    health, core = replay_direct_jobs(mixed, jobs=1)
    assert isinstance(core, MonitorCore) and health == replay_direct(mixed)[0]
    assert shard_rigs(["c", "a", "b", "a"], 2) == {"a": 0, "b": 1, "c": 0}
    with pytest.raises(ValueError, match="jobs 0"):
        replay_direct_jobs(mixed, jobs=0)


def test_a_worker_that_fails_or_dies_is_an_error_not_missing_health(mixed):
    parent = os.getpid()

    def failing():
        if os.getpid() != parent:
            raise OSError("disk on fire")
        return MonitorCore()

    with pytest.raises(RuntimeError, match=r"replay worker [12] of 2 failed: OSError: disk on fire"):
        replay_direct_jobs(mixed, jobs=2, make_core=failing)

    def dying():
        if os.getpid() != parent:
            os._exit(3)
        return MonitorCore()

    with pytest.raises(RuntimeError, match=r"replay worker [12] of 2 died \(exit status 3\)"):
        replay_direct_jobs(mixed, jobs=2, make_core=dying)


def test_cli_jobs_gives_the_same_file(mixed, tmp_path, capsys):
    from hydromon.cli.main import main

    outs = []
    for jobs in ("1", "2"):
        out = tmp_path / f"h{jobs}.jsonl"
        assert main(["replay", str(mixed), "--direct", "--jobs", jobs, "--out", str(out)]) == 0
        outs.append(out.read_bytes())
    assert outs[0] == outs[1] and outs[0]
    err = capsys.readouterr().err
    assert err.count("hydromon replay: ") == 2 and "8 rig(s)" in err
    assert main(["replay", str(mixed), "--direct", "--jobs", "0"]) == 2
    assert "--jobs 0 must be >= 1" in capsys.readouterr().err
    assert main(["replay", str(mixed), "--jobs", "2"]) == 2
    assert "--jobs goes with --direct" in capsys.readouterr().err


def test_progress_climbs_to_the_end_of_the_window(mixed):
    for run in (lambda p: replay_direct(mixed, progress=p), lambda p: replay_direct_jobs(mixed, jobs=2, progress=p),
                lambda p: replay_direct_jobs(mixed, jobs=2, start=1.0, duration=2.0, progress=p)):
        seen = []
        run(lambda done, total: seen.append((done, total)))
        done = [d for d, _ in seen]
        assert done == sorted(done) and len({t for _, t in seen}) == 1
        assert seen[-1][0] == seen[-1][1] and seen[-1][1] in (2.0, pytest.approx(4.0, abs=0.02))
