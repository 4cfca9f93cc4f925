"""A command that runs the compiled kernels on a cold numba cache says why it is slow."""

from __future__ import annotations

import argparse

import pytest

from hydromon import cli
from plant_sim import _jitcache


def test_is_cold_reads_the_cache_directory(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert _jitcache.is_cold()
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "kernel-1.py311.nbi").write_bytes(b"")
    assert not _jitcache.is_cold()
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    assert not _jitcache.is_cold()  # numba caches beside the sources: unknown, so no claim


def _args(command, kernels, **kw):
    return argparse.Namespace(command=command, _kernels=kernels, **kw)


@pytest.mark.parametrize("kernels, cold, shown", [
    (True, True, True), (True, False, False), (False, True, False),
    (lambda a: a.direct, True, True),
])
def test_notice_only_for_a_kernel_command_on_a_cold_cache(monkeypatch, capsys, kernels, cold, shown):
    monkeypatch.setattr(_jitcache, "is_cold", lambda: cold)
    monkeypatch.setattr(cli, "COMPILE_NOTICE_AFTER_S", 0.0)
    timer = cli._compile_notice(_args("evaluate", kernels, direct=True))
    assert (timer is not None) == shown
    if timer is not None:
        timer.join(5)
        assert "hydromon evaluate: first run of this version on this machine: compiling" in capsys.readouterr().err


def test_replay_without_direct_compiles_nothing(monkeypatch):
    monkeypatch.setattr(_jitcache, "is_cold", lambda: True)
    args = cli.build_parser().parse_args(["replay", "x.mcap"])
    assert cli._compile_notice(args) is None
    args = cli.build_parser().parse_args(["replay", "x.mcap", "--direct"])
    timer = cli._compile_notice(args)
    assert timer is not None
    timer.cancel()


def test_every_command_that_runs_kernels_declares_it():
    parser = cli.build_parser()
    declared = {name for name in ("audit", "bench", "calibrate", "evaluate", "monitor", "reproduce", "sim")
                if getattr(parser.parse_args([name] + (["f"] if name in ("audit", "evaluate") else [])),
                           "_kernels", False)}
    assert declared == {"audit", "bench", "calibrate", "evaluate", "monitor", "reproduce", "sim"}


def test_the_notice_is_cancelled_when_the_command_ends(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(_jitcache, "is_cold", lambda: True)
    monkeypatch.setattr(cli, "COMPILE_NOTICE_AFTER_S", 30.0)
    code = cli.main(["evaluate", str(tmp_path / "missing.csv")])  # fails at once
    assert code == 2
    import threading
    timers = [t for t in threading.enumerate() if isinstance(t, threading.Timer)]
    for t in timers:
        t.join(5)  # a cancelled timer ends at once; one still waiting its 30 s would not
    assert not [t for t in timers if t.is_alive()]
    assert "compiling" not in capsys.readouterr().err
