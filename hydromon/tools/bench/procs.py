"""Shared helpers of ``hydromon bench``: progress lines, and child processes (CPU time, waiting
for a log line, stopping)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time


def _log(msg: str) -> None:
    print(f"hydromon bench: {msg}", file=sys.stderr, flush=True)


def _cpu_seconds(pid: int) -> float:
    """utime + stime of a process (all its threads) [s], from /proc/<pid>/stat."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _wait_for(path: str, text: str, proc, timeout: float) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        with open(path) as f:
            if text in f.read():
                return
        if proc.poll() is not None:
            with open(path) as f:
                raise RuntimeError(f"process exited ({proc.returncode}) before {text!r}: {f.read()[-2000:]}")
        time.sleep(0.05)
    raise RuntimeError(f"timed out waiting for {text!r} in {path}")


def _stop(proc, timeout: float = 30.0) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)
