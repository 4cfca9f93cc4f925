"""A command that runs the compiled kernels on a cold numba cache says why it is slow."""

from __future__ import annotations

import argparse

import pytest

from hydromon.tools import jitcache as _jitcache
from hydromon.cli import main as cli


def _compiled(cache, root, pkg):
    sub = cache / _jitcache.numba_subdir(root / pkg)
    sub.mkdir(parents=True, exist_ok=True)
    (sub / "kernel-1.py311.nbi").write_bytes(b"")


def test_is_cold_reads_the_cache_directory(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert _jitcache.is_cold()
    for pkg in _jitcache._PACKAGES:
        _compiled(tmp_path, _jitcache._ROOT, pkg)
    assert not _jitcache.is_cold()
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    assert not _jitcache.is_cold()  # numba caches beside the sources: unknown, so no claim


def test_is_cold_for_a_second_checkout_of_the_same_sources(tmp_path, monkeypatch):
    # the cache directory is keyed on the sources' content, so a clone shares it with the
    # checkout it came from; numba keys each kernel on its file's path, so the clone compiles
    # all of them again (a monitor sat a minute silent, at 50 % CPU, with no notice)
    cache = tmp_path / "cache"
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(cache))
    first, clone = tmp_path / "main", tmp_path / "clone"
    for pkg in _jitcache._PACKAGES:
        _compiled(cache, first, pkg)
    assert not _jitcache.is_cold(first)
    assert _jitcache.is_cold(clone)
    _compiled(cache, clone, "plant_sim")
    assert _jitcache.is_cold(clone)  # the monitor's kernels still to compile
    _compiled(cache, clone, "monitor")
    assert not _jitcache.is_cold(clone)
    # the name numba itself gives the directory
    from numba.core.caching import _CacheLocator

    assert _jitcache.numba_subdir(clone / "monitor") == _CacheLocator.get_suitable_cache_subpath(
        str(clone / "monitor" / "pipeline.py"))


def test_an_audit_is_cold_until_the_kernels_it_runs_are_cached(tmp_path, monkeypatch):
    """The audit runs kernels of monitor (its outlier gate), monitor/audit and plant_sim, which
    numba caches under those directories' names: the default packages' kernels cached, it still
    compiles monitor/audit's; with all three cached it compiles nothing."""
    from hydromon.cli.commands import audit

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(cli, "COMPILE_NOTICE_AFTER_S", 60.0)
    args = cli.build_parser().parse_args(["audit", "x.csv"])
    assert args._kernels == audit.KERNELS == ("monitor", "monitor/audit", "plant_sim")
    for d in audit.KERNELS:
        assert any("@njit" in f.read_text() for f in (_jitcache._ROOT / d).glob("*.py")), d
    for d in _jitcache._PACKAGES:
        _compiled(tmp_path, _jitcache._ROOT, d)
    assert not _jitcache.is_cold()
    timer = cli._compile_notice(args)
    assert timer is not None  # monitor/audit's kernels are not cached yet
    timer.cancel()
    _compiled(tmp_path, _jitcache._ROOT, "monitor/audit")
    assert cli._compile_notice(args) is None


def _args(command, kernels, **kw):
    return argparse.Namespace(command=command, _kernels=kernels, **kw)


@pytest.mark.parametrize("kernels, cold, shown", [
    (True, True, True), (True, False, False), (False, True, False),
    (lambda a: a.direct, True, True),
])
def test_notice_only_for_a_kernel_command_on_a_cold_cache(monkeypatch, capsys, kernels, cold, shown):
    monkeypatch.setattr(_jitcache, "is_cold", lambda **kw: cold)
    monkeypatch.setattr(cli, "COMPILE_NOTICE_AFTER_S", 0.0)
    timer = cli._compile_notice(_args("evaluate", kernels, direct=True))
    assert (timer is not None) == shown
    if timer is not None:
        timer.join(5)
        assert "hydromon evaluate: first run of this version on this machine: compiling" in capsys.readouterr().err


def test_replay_without_direct_compiles_nothing(monkeypatch):
    monkeypatch.setattr(_jitcache, "is_cold", lambda **kw: True)
    args = cli.build_parser().parse_args(["replay", "x.mcap"])
    assert cli._compile_notice(args) is None
    args = cli.build_parser().parse_args(["replay", "x.mcap", "--direct"])
    timer = cli._compile_notice(args)
    assert timer is not None
    timer.cancel()


def test_every_command_that_runs_kernels_declares_it():
    parser = cli.build_parser()
    declared = {name for name in ("audit", "bench", "calibrate", "demo", "evaluate", "monitor", "reproduce", "sim")
                if getattr(parser.parse_args([name] + (["f"] if name in ("audit", "evaluate") else [])),
                           "_kernels", False)}
    assert declared == {"audit", "bench", "calibrate", "demo", "evaluate", "monitor", "reproduce", "sim"}


def test_the_notice_is_cancelled_when_the_command_ends(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(_jitcache, "is_cold", lambda **kw: True)
    monkeypatch.setattr(cli, "COMPILE_NOTICE_AFTER_S", 30.0)
    code = cli.main(["evaluate", str(tmp_path / "missing.csv")])  # fails at once
    assert code == 2
    import threading
    timers = [t for t in threading.enumerate() if isinstance(t, threading.Timer)]
    for t in timers:
        t.join(5)  # a cancelled timer ends at once; one still waiting its 30 s would not
    assert not [t for t in timers if t.is_alive()]
    assert "compiling" not in capsys.readouterr().err
