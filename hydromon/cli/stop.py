"""SIGINT/SIGTERM -> a command's stop event, without a deadlock in the signal handler."""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Callable

SIGNALS = (signal.SIGINT, signal.SIGTERM)


def stop_on_signals(stop: threading.Event, signals=SIGNALS) -> Callable[[], None]:
    """Set ``stop`` when one of ``signals`` arrives; returns the function that puts the previous
    handlers back (call it in a ``finally``). Call from the main thread.

    The handler does not call ``stop.set()``: Python runs a handler in the main thread between
    two bytecodes of whatever it was running, and a node's main thread spends its idle time in
    ``stop.wait(poll)``, which holds the event's lock (a plain Lock, not reentrant) for a few
    bytecodes on its way in and out. A handler that ran there and called ``stop.set()`` (which
    takes that lock) waited for itself for good: the node never stopped on SIGTERM (caught in
    ``hydromon record``, 1 of 50 SIGTERMs with a CPU hog on the machine; the stack was
    ``Event.wait`` -> ``Condition._is_owned`` -> the handler -> ``Event.set`` -> ``Condition.__enter__``).
    So the handler only writes a byte to a pipe (no lock); a daemon thread reads it and sets
    ``stop``, as any other thread may.
    """
    r, w = os.pipe()
    os.set_blocking(w, False)

    def handler(signum, frame) -> None:
        try:
            os.write(w, b"s")
        except OSError:  # the pipe is full (a storm of signals): a byte is already waiting in it
            pass

    def setter() -> None:
        try:
            while os.read(r, 64):  # b"" once the write end is closed: the command is over
                stop.set()
        finally:
            os.close(r)

    previous = {}
    try:
        for sig in signals:
            previous[sig] = signal.signal(sig, handler)  # ValueError outside the main thread
    except BaseException:
        for sig, old in previous.items():
            signal.signal(sig, old)
        os.close(r)
        os.close(w)
        raise
    thread = threading.Thread(target=setter, name="stop-on-signals", daemon=True)
    thread.start()

    def restore() -> None:
        for sig, old in previous.items():
            signal.signal(sig, old)
        os.close(w)
        thread.join(5.0)

    return restore
