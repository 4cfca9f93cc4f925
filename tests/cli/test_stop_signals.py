"""SIGINT/SIGTERM stop a node even when they land while its main thread holds the stop event's lock.

A node's main thread idles in ``stop.wait(poll)``; ``threading.Event.wait`` holds the event's lock
(a plain Lock) for a few bytecodes on its way in and out, and Python runs a signal handler between
two bytecodes of the main thread. A handler that called ``stop.set()`` there waited for that lock,
held by the very thread it ran in: ``hydromon record`` did not stop on SIGTERM (1 in 50 with a CPU
hog on the machine; a test failed once in a full suite run). These tests put the signal exactly
there: the command's stop event locked while the signal arrives.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading

import pytest

from hydromon.cli.stop import stop_on_signals

# `hydromon CMD` in a child process with the bus and the node's loop replaced by one that receives
# the signal while it holds the stop event's lock, then waits for the event as the node does
_CHILD = textwrap.dedent("""
    import contextlib, signal, sys, threading
    import hydromon.bus.monitor, hydromon.bus.recorder
    from hydromon.cli.commands import monitor, record
    from hydromon.bus.recorder import RecordResult

    def loop(*args, stop_event, **kw):
        with stop_event._cond:  # where Event.wait holds it
            signal.raise_signal(signal.SIG{sig})
            x = [0] * 3  # a few bytecodes with the lock held: the handler runs in one of them
        if not stop_event.wait(20):
            print("stop event never set", flush=True)
            sys.exit(3)
        return kw.get("core") or RecordResult()

    hydromon.bus.monitor.run_monitor = loop
    hydromon.bus.recorder.record = loop
    monitor.session_from_args = record.session_from_args = lambda args: contextlib.nullcontext(None)
    from hydromon.cli.main import main
    sys.exit(main(sys.argv[1:]))
""")


@pytest.mark.timeout(120)
@pytest.mark.parametrize("sig", ["TERM", "INT"])
@pytest.mark.parametrize("command", [["monitor"], ["record", "--out", "{tmp}/x.mcap"]])
def test_a_signal_while_the_stop_event_is_locked_stops_the_command(tmp_path, command, sig):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in command]
    proc = subprocess.Popen([sys.executable, "-c", _CHILD.replace("{sig}", sig), *argv],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        out, _ = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, _ = proc.communicate()
        pytest.fail(f"hydromon {command[0]} hung after SIG{sig} (the handler waiting for the stop "
                    f"event's lock, held by its own thread); its output: {out[-2000:]}")
    assert proc.returncode == 0, out[-2000:]


def test_stop_on_signals_sets_the_event_and_puts_the_handlers_back():
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    stop = threading.Event()
    restore = stop_on_signals(stop)
    try:
        with stop._cond:
            signal.raise_signal(signal.SIGTERM)  # the handler runs here, with the lock held
            [0] * 3
        assert stop.wait(10)
    finally:
        restore()
    assert {s: signal.getsignal(s) for s in before} == before
    assert not any(t.name == "stop-on-signals" for t in threading.enumerate())


def test_stop_on_signals_outside_the_main_thread_is_refused_and_leaks_nothing():
    fds = len(os.listdir("/proc/self/fd"))
    errors = []

    def other():
        try:
            stop_on_signals(threading.Event())
        except ValueError as exc:
            errors.append(exc)

    t = threading.Thread(target=other)
    t.start()
    t.join()
    assert len(errors) == 1
    assert len(os.listdir("/proc/self/fd")) == fds
