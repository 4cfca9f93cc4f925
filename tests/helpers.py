"""Shared test helpers: polling for a condition, where a rig's health messages fall, a taken port, node
processes, a run fed to a MonitorCore."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import orjson

from hydromon.bus.session import on_a_free_port
from monitor.evaluations import eval_phase


def wait_for(pred, timeout_s: float, what: str, alive=None, poll_s: float = 0.02) -> None:
    """Poll ``pred()`` until true; AssertionError after ``timeout_s`` [s], or as soon as
    ``alive()`` (optional: e.g. a check that the node processes still run) raises."""
    deadline = time.monotonic() + timeout_s
    while not pred():
        if alive is not None:
            alive()
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(poll_s)


def held_port() -> tuple[socket.socket, str]:
    """A socket listening on a free loopback port, and its ``tcp/127.0.0.1:PORT``: a port another
    process took (close the socket to give it back)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.bind(("127.0.0.1", 0))
    s.listen()
    return s, f"tcp/127.0.0.1:{s.getsockname()[1]}"


def taken_first(monkeypatch, taken: str) -> None:
    """The race of ``hydromon.bus.session.free_tcp_endpoint``, made certain: it hands out ``taken`` (a
    port someone took after it was found free) first, then free ports."""
    from hydromon.bus import session as bus

    picks, real = [taken], bus.free_tcp_endpoint
    monkeypatch.setattr(bus, "free_tcp_endpoint", lambda host="127.0.0.1": picks.pop(0) if picks else real(host))


def health_seqs(rig_id: str, n: int, eval_every: int = 10, first: int = 0) -> list[int]:
    """Seqs of the samples after which the monitor (staggered, ``monitor.evaluations.eval_phase``)
    reports rig ``rig_id`` when it takes samples first .. n-1 with no restart."""
    ph = eval_phase(rig_id, eval_every)
    return [s for s in range(first, n) if (s - first + 1 + ph) % eval_every == 0]


def window_end(rig_id: str, s: int, eval_every: int = 10) -> int:
    """Seq of the health message whose window holds sample s (no restart)."""
    ph = eval_phase(rig_id, eval_every)
    e = s
    while (e + 1 + ph) % eval_every:
        e += 1
    return e


def assert_clean_but_flagged(rig_id: str, got: list, clean: list, bad_after) -> None:
    """A rig's health payloads ``got`` are the clean run's verdicts ``clean``, byte for byte except
    status ``bad-input`` in exactly the windows after a rejected message (after sample s of
    ``bad_after``: the next window)."""
    windows = {window_end(rig_id, s + 1) for s in bad_after}
    assert len(got) == len(clean)
    for g, w in zip(got, clean):
        g, w = orjson.loads(g), orjson.loads(w)
        if g["seq"] in windows:
            assert g["status"] == "bad-input"
            w["status"] = "bad-input"
        assert g == w
    assert sum(orjson.loads(p)["status"] == "bad-input" for p in got) == len(windows)


# -- malformed input ------------------------------------------------------------------------------

GOOD = {"seq": 5, "t": 0.05, "ug": 0.1, "x1": 0.01, "x3": 5e6, "x4": 6e6, "x5": 1e-5}
DROP = object()


def sample_with(**kw) -> bytes:
    """A contract sample payload with fields changed (``DROP`` removes one)."""
    d = {**GOOD, **kw}
    return orjson.dumps({k: v for k, v in d.items() if v is not DROP})


def _token(value: str, **kw) -> bytes:
    """A payload with a bare JSON token (NaN, Infinity, 1e400) as one field's value."""
    field = next(iter(kw))
    return sample_with(**{field: 0.123456}).replace(b"0.123456", value.encode())


# (reason, payload) on a sample key: every kind of malformed sample
BAD_SAMPLES = [
    ("not-json", b"{not json"),
    ("not-json", b""),
    ("not-json", b"\xff\xfe\x00"),
    ("missing-field", sample_with(x5=DROP)),
    ("missing-field", sample_with(seq=DROP)),
    ("wrong-type", sample_with(x1="0.01")),
    ("wrong-type", sample_with(seq=3.0)),
    ("wrong-type", sample_with(ug=True)),
    ("wrong-type", sample_with(x3=None)),
    ("wrong-type", b"[1, 2, 3]"),
    ("wrong-type", b"42"),
    ("non-finite", _token("NaN", x1=1)),
    ("non-finite", _token("Infinity", x3=1)),
    ("non-finite", _token("-Infinity", x4=1)),
    ("non-finite", _token("1e400", t=1)),
    ("non-finite", sample_with(x1="nan")),
    ("non-finite", sample_with(ug="-inf")),
    ("unknown-field", sample_with(z=1.0)),
    ("bad-value", sample_with(seq=-1)),
    ("bad-value", sample_with(seq=2**63)),  # beyond SEQ_MAX (the monitor keeps seqs as int64)
    ("bad-value", sample_with(x3=1e300)),   # beyond SAMPLE_LIMITS: finite, but would wreck the estimates
    ("bad-value", sample_with(x1=-10.5)),
    ("bad-value", sample_with(x5=0.2)),
    ("bad-value", sample_with(ug=2000)),
]


def chunk_spans(data: bytes) -> list[tuple[int, int, int]]:
    """``(record start, record end, compressed size)`` of every chunk of a complete MCAP, in file order."""
    import io

    from mcap.reader import make_reader

    idx = make_reader(io.BytesIO(data)).get_summary().chunk_indexes
    return sorted((c.chunk_start_offset, c.chunk_start_offset + c.chunk_length, c.compressed_size) for c in idx)


def flip_in_chunk(data: bytes, i: int, bit: int = 2) -> bytes:
    """``data`` with one bit flipped in the middle of chunk ``i``'s compressed bytes (framing intact)."""
    _start, end, compressed = chunk_spans(data)[i]
    bad = bytearray(data)
    bad[end - compressed // 2] ^= 1 << bit
    return bytes(bad)


def fleet_messages(spec, seconds: float, ns: str = "hydro", frame: int | None = None) -> list[tuple[str, bytes]]:
    """What the sim node would publish for ``spec`` (a FleetSpec) over ``seconds`` [s]: configs,
    then samples interleaved rig by rig (with ``frame``: frames of that many samples)."""
    from hydromon.engine.frames import block_frames
    from hydromon.engine.samples import sample_payload
    from hydromon.store.simfiles import iter_blocks

    fleet = spec.build()
    msgs = [(f"{ns}/rig/{i}/config", orjson.dumps(c.model_dump(mode="json")))
            for i, c in zip(spec.ids, fleet.configs)]
    for blk in iter_blocks(fleet, int(round(seconds / fleet.h)), block=200):
        if frame is not None:
            for j0 in range(0, len(blk.t), frame):
                payloads = block_frames(blk, j0, min(j0 + frame, len(blk.t)))
                msgs += [(f"{ns}/rig/{rig}/frame", p) for rig, p in zip(spec.ids, payloads)]
            continue
        rows = blk.samples.tolist()
        for j, (seq, t) in enumerate(zip(blk.seq.tolist(), blk.t.tolist())):
            for r, rig in enumerate(spec.ids):
                msgs.append((f"{ns}/rig/{rig}/sample", sample_payload(seq, t, rows[r][j])))
    return msgs


def without_node(payload: bytes) -> bytes:
    """A health payload without the ``node`` and ``epoch`` that name the monitor that said it
    (they end the payload): what a core that names no node gives for the same samples."""
    h = orjson.loads(payload)
    h.pop("node", None)
    h.pop("epoch", None)
    return orjson.dumps(h)


def by_rig(health) -> dict[str, list[bytes]]:
    """Health payloads ``[(key, payload)]`` by rig id."""
    out = {}
    for key, payload in health:
        out.setdefault(key.split("/")[2], []).append(payload)
    return out


# -- MCAP recordings in memory ------------------------------------------------------------
SECOND_NS = 1_000_000_000  # [ns]


def sample_bytes(seq: int, t: float, **kw) -> bytes:
    """A contract sample's JSON with made-up values (``kw`` overrides them)."""
    vals = dict(ug=0.01 * seq, x1=1e-3 * np.sin(seq), x3=6e6 + seq, x4=3e6 - seq, x5=1e-5 * seq)
    vals.update(kw)
    from hydromon.contract import Sample

    return Sample(seq=seq, t=t, **vals).model_dump_json().encode()


def health_bytes(seq: int, t: float) -> bytes:
    """A contract health payload's JSON."""
    from hydromon.contract import Health

    return Health(seq=seq, t=t, grade="health", level=0, confidence=0.9, params={"m": 800.0},
                  param_grades={"m": "health"}, status="ok").model_dump_json().encode()


def write_messages(msgs, **kw) -> tuple[bytes, list[int]]:
    """Write ``(key, payload, log_ns, pub_ns)``; return the bytes and the size after each write."""
    import io

    from hydromon.store.mcap_write import RecordingWriter

    buf = io.BytesIO()
    sizes = []
    w = RecordingWriter(buf, **kw)
    for m in msgs:
        w.write(*m)
        sizes.append(buf.tell())
    w.close()
    return buf.getvalue(), sizes


def sample_stream(n: int, dt_ns: int = 10_000_000, rig: str = "r1", t0_ns: int = 5 * SECOND_NS):
    """``n`` sample messages ``(key, payload, log_ns, pub_ns)`` of one rig, ``dt_ns`` apart."""
    return [(f"hydro/rig/{rig}/sample", sample_bytes(i, i * dt_ns / SECOND_NS), t0_ns + i * dt_ns, i * dt_ns)
            for i in range(n)]


def config_and_samples(n: int = 500):
    """A rig config, then samples: the messages of a one-rig recording."""
    from hydromon.contract import RigConfig

    cfg = RigConfig().model_dump_json().encode()
    return [("hydro/rig/r1/config", cfg, 5 * SECOND_NS, 5 * SECOND_NS)] + sample_stream(n)[1:]


def working_point_sample(seq: int, ints: bool = False) -> bytes:
    """A sample payload of a plant near its working point."""
    # values of a plant near its working point; `ints` sends t and ug as JSON integers (valid,
    # but not what the sim sends: the per-message path takes them)
    t = seq // 100 if ints else seq * 0.01
    ug = 2 if ints else 2.0 + 0.5 * ((seq * 7919) % 13) / 13
    return orjson.dumps({"seq": seq, "t": t, "ug": ug, "x1": 0.01 + 1e-4 * (seq % 17), "x3": 6e6 + 1e4 * (seq % 5),
                         "x4": 5e6 - 1e4 * (seq % 3), "x5": 1e-5 * (1 + seq % 4)})


# -- node processes ---------------------------------------------------------------------------
CLI = [sys.executable, "-m", "hydromon.cli"]


class Procs:
    """Node processes by name, each with its output in ``<dir>/<name>.log``; ``close`` ends
    whatever still runs (SIGTERM, then SIGKILL), so nothing outlives the test."""

    def __init__(self, directory):
        self.dir = directory
        self.procs: dict[str, subprocess.Popen] = {}
        self._logs = []
        self.finished: set[str] = set()  # names expected to have exited by themselves

    def start(self, name: str, *args: str) -> subprocess.Popen:
        log = open(self.dir / f"{name}.log", "wb")
        self._logs.append(log)
        p = subprocess.Popen(CLI + list(args), stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                             env={**os.environ, "PYTHONUNBUFFERED": "1"})
        self.procs[name] = p
        return p

    def start_listening(self, name: str, *args: str, ready: str, timeout_s: float = 60) -> str:
        """Start a node with ``--listen tcp/127.0.0.1:PORT`` on a free port and wait for ``ready``
        in its output; return the endpoint. If another process took the port before the node
        bound it (it exits: "Address already in use"), start it again on another port."""
        def start(ep):
            self.start(name, *args, "--listen", ep)
            wait_for(lambda: ready in self.log(name), timeout_s, f"the {name}", alive=self.check_alive)

        return on_a_free_port(start)[1]

    def log(self, name: str) -> str:
        return (self.dir / f"{name}.log").read_text(errors="replace")

    def check_alive(self) -> None:
        for name, p in self.procs.items():
            if name not in self.finished and p.poll() is not None:
                raise AssertionError(f"{name} exited early with {p.returncode}:\n{self.log(name)[-3000:]}")

    def wait(self, name: str, timeout_s: float) -> int:
        self.finished.add(name)
        try:
            return self.procs[name].wait(timeout_s)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"{name} still running after {timeout_s} s:\n{self.log(name)[-3000:]}") from None

    def stop(self, name: str, sig=signal.SIGINT, timeout_s: float = 30) -> int:
        """Ask a node to stop (it closes cleanly on SIGINT/SIGTERM) and return its exit code."""
        self.finished.add(name)
        self.procs[name].send_signal(sig)
        return self.wait(name, timeout_s)

    def close(self) -> None:
        for p in reversed(list(self.procs.values())):
            if p.poll() is None:
                p.terminate()
        for p in reversed(list(self.procs.values())):
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(10)
        for log in self._logs:
            log.close()


def core_messages(run, samples, frame=None, rig="a", ns="hydro"):
    """A simulated run's ``samples`` as the bus messages of rig ``rig``: one per sample, or
    frames of ``frame`` samples."""
    from hydromon.engine.frames import frame_payload
    from hydromon.engine.samples import sample_payload

    if frame is None:
        return [(f"{ns}/rig/{rig}/sample", sample_payload(k, float(run.t[k]), samples[k].tolist()))
                for k in range(len(samples))]
    return [(f"{ns}/rig/{rig}/frame", frame_payload(k, run.t[k:k + frame].tolist(), samples[k:k + frame].T.tolist()))
            for k in range(0, len(samples), frame)]


def run_core(msgs, batch=None, ns="hydro"):
    """``msgs`` through a fresh MonitorCore, ``batch`` messages a call (None: all at once):
    ``(health payloads, [(rig, warning)])``."""
    from hydromon.engine.core import MonitorCore

    warnings = []
    core = MonitorCore(ns, on_warning=lambda rig, msg: warnings.append((rig, msg)))
    out, step = [], batch or len(msgs)
    for j in range(0, len(msgs), step):
        out += core.process(msgs[j:j + step])
    return [orjson.loads(p) for k, p in out if k.endswith("/health")], warnings


def health_however_batched(run, samples, ns="hydro"):
    """The health payloads of ``samples`` through a MonitorCore, asserted the same whether the
    messages come all at once, in batches of 1, 7 or 64, or as frames of 10 three at a time."""
    one, _ = run_core(core_messages(run, samples, ns=ns), ns=ns)
    for batch in (1, 7, 64):
        assert run_core(core_messages(run, samples, ns=ns), batch, ns)[0] == one, batch
    assert run_core(core_messages(run, samples, frame=10, ns=ns), 3, ns)[0] == one
    return one
