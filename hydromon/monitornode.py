"""The monitor node: rig samples in, health verdicts out (DESIGN.md 1, 3).

Two layers:

* :class:`MonitorCore` is the node without the bus: it takes raw ``(key, payload bytes)``
  messages in arrival order and returns the ``(health key, health payload)`` pairs to
  publish. It has no clock, no threads and no I/O, so the live node, ``hydromon replay``
  over the bus and ``hydromon replay --direct`` all give the same health for the same
  message sequence, and tests drive it in memory.
* :func:`run_monitor` is the zenoh shell around it: subscribers with FIFO channel handlers
  (zenoh forbids blocking or calling its API inside callbacks), a loop that drains
  everything queued into one batch (``try_recv`` until empty; the 1.x handlers have no
  ``recv`` with a timeout, so an empty channel waits ``poll_s`` on the stop event), one
  publisher per rig's health key, a liveliness token ``<ns>/monitor/<node>`` and a
  queryable on ``<ns>/rig/*/health`` that answers with each rig's latest health.

Validation at the edge (never crash, never feed an estimator): a message is rejected, and
counted under a reason, when

=================  ===================================================================
``bad-key``        the key is not ``<ns>/rig/<chunk>/sample`` or ``.../config``
``bad-rig-id``     the rig chunk is not 1-64 chars of ``[A-Za-z0-9_-]``
``not-json``       the payload does not parse as JSON
``non-finite``     NaN or +-inf, as a JSON token (``NaN``, ``Infinity``, ``1e400``) or as
                   a string spelling one (``"nan"``, ``"inf"``)
``missing-field``  a field of the contract model is absent
``wrong-type``     not a JSON object, or a field of the wrong type (a string, a bool, a
                   float seq)
``unknown-field``  a field the contract does not have (models forbid extras)
``bad-value``      a value out of its range (seq < 0, a non-positive area) or a config
                   whose sample rate the monitor does not run at
=================  ===================================================================

``<ns>/rig/<id>/health`` keys are the monitor's own output (recordings hold them): they
are skipped and counted as ``ignored``, not rejected.

Sequence numbers, per rig: a seq at or below the last one taken is dropped (counted as
``duplicate`` when equal, ``out_of_order`` when lower), except ``seq == 0`` after a
higher seq, which is a restart of the rig (or a looped replay): the rig's estimates are
reset (``restarts``). A seq above ``last + 1`` is a gap (``gaps``, ``missing`` samples):
the rig's filters restart (``Fleet.reset_signals``; estimates carry on).

Health status, in order of precedence: ``bad-input`` if a message on this rig's sample
key was rejected since its previous health message; ``stale`` while fewer than
``stale_samples`` (default ``eval_every``) samples have followed the last gap, so the
first health after a gap is always stale; ``converging`` while the estimator has not
converged or cannot place the grade (level -1); else ``ok``.

Health payloads carry finite numbers only (JSON has no NaN/inf): a parameter whose
estimate or standard error is not finite (an equation without enough rows has infinite
standard errors) is left out of ``params`` / ``std_errors``; confidence is clipped to
[0, 1] (0 if not finite). ``seq`` and ``t`` are those of the sample after which the rig
was evaluated; ``level`` is null and ``grade`` ``"unknown"`` when the level is -1.
"""

from __future__ import annotations

import json
import logging
import math
import re
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
import orjson
import zenoh
from pydantic import ValidationError

from hydromon.bus import JSON
from hydromon.quietgc import QuietGC
from hydromon.contract import (DEFAULT_NAMESPACE, GRADES, PARAM_NAMES, RigConfig, Sample, _check_ns,
                               health_key, liveliness_key, valid_rig_id)
from monitor.pipeline import Fleet, warm_up

__all__ = ["MonitorCore", "MonitorCounters", "RateLimitedLog", "run_monitor", "REJECT_REASONS"]

log = logging.getLogger(__name__)

REJECT_REASONS = ("bad-key", "bad-rig-id", "not-json", "non-finite", "missing-field", "wrong-type",
                  "unknown-field", "bad-value")
_SAMPLE_FIELDS = ("seq", "t", "ug", "x1", "x3", "x4", "x5")
_SAMPLE_FIELD_SET = frozenset(_SAMPLE_FIELDS)
_NUM = (float, int)


class Rejected(ValueError):
    """A message failed validation at the edge; ``reason`` is one of REJECT_REASONS."""

    def __init__(self, reason: str, detail: str):
        super().__init__(f"{reason}: {detail}")
        self.reason, self.detail = reason, detail


@dataclass
class MonitorCounters:
    """What the monitor did with its input (all counts of messages, except ``missing``)."""

    accepted: int = 0          # samples fed to the estimators
    configs: int = 0           # valid config messages
    config_changes: int = 0    # configs that changed a known rig (its estimates restarted)
    rejected: dict = field(default_factory=lambda: {r: 0 for r in REJECT_REASONS})
    duplicate: int = 0         # seq equal to the last taken
    out_of_order: int = 0      # seq below the last taken
    gaps: int = 0              # seq jumps
    missing: int = 0           # samples skipped by those jumps
    restarts: int = 0          # seq back to 0
    ignored: int = 0           # health messages (our own output kind)
    health: int = 0            # health messages produced

    @property
    def dropped_seq(self) -> int:
        return self.duplicate + self.out_of_order

    @property
    def rejected_total(self) -> int:
        return sum(self.rejected.values())

    def as_dict(self) -> dict:
        return {"accepted": self.accepted, "configs": self.configs, "config_changes": self.config_changes,
                "rejected": dict(self.rejected), "duplicate": self.duplicate,
                "out_of_order": self.out_of_order, "gaps": self.gaps, "missing": self.missing,
                "restarts": self.restarts, "ignored": self.ignored, "health": self.health}


def _nonfinite_string(v) -> bool:
    if not isinstance(v, str):
        return False
    try:
        return not math.isfinite(float(v))
    except ValueError:
        return False


def _classify(exc: ValidationError, obj: dict) -> tuple[str, str]:
    """Reason and a short detail for a pydantic validation error of a JSON object."""
    errors = exc.errors()
    kinds = []
    for e in errors:
        loc = ".".join(map(str, e.get("loc", ()))) or "<payload>"
        typ = e.get("type", "")
        value = obj.get(e["loc"][0]) if e.get("loc") and isinstance(obj, dict) else None
        if typ == "missing":
            kinds.append(("missing-field", loc))
        elif typ == "finite_number" or "finite" in e.get("msg", "") or _nonfinite_string(value):
            kinds.append(("non-finite", loc))
        elif typ == "extra_forbidden":
            kinds.append(("unknown-field", loc))
        elif typ in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
            kinds.append(("bad-value", loc))
        else:
            kinds.append(("wrong-type", loc))
    order = {r: i for i, r in enumerate(REJECT_REASONS)}
    reason = min((k for k, _ in kinds), key=order.__getitem__)
    where = ", ".join(loc for k, loc in kinds if k == reason)
    return reason, f"{where}: {errors[0].get('msg', '')}" if len(kinds) == 1 else where


def decode_json(payload: bytes):
    """Parse a JSON payload; Rejected('non-finite') for NaN/Infinity tokens or overflow,
    Rejected('not-json') for anything else that is not JSON."""
    try:
        return orjson.loads(payload)
    except orjson.JSONDecodeError as exc:
        try:  # the stdlib parser also takes NaN, Infinity and overflowing numbers
            json.loads(payload)
        except (ValueError, UnicodeDecodeError, RecursionError):
            raise Rejected("not-json", str(exc)) from None
        raise Rejected("non-finite", "NaN or infinity in the JSON") from None


def parse_sample(obj) -> tuple[int, float, float, float, float, float, float]:
    """``(seq, t, ug, x1, x3, x4, x5)`` of a decoded sample payload, validated as
    ``contract.Sample`` (a fast path for the common valid case; the model decides the rest)."""
    if type(obj) is dict and len(obj) == 7 and obj.keys() == _SAMPLE_FIELD_SET:
        seq = obj["seq"]
        t, ug, x1, x3, x4, x5 = obj["t"], obj["ug"], obj["x1"], obj["x3"], obj["x4"], obj["x5"]
        # the common case, what our sim sends: an int seq and six floats (no conversions)
        if type(seq) is int and seq >= 0 and type(t) is float and type(ug) is float and type(x1) is float \
                and type(x3) is float and type(x4) is float and type(x5) is float \
                and math.isfinite(t + ug + x1 + x3 + x4 + x5):
            return (seq, t, ug, x1, x3, x4, x5)
        if type(seq) is int and seq >= 0:
            try:
                # finite floats (orjson gives no NaN/inf) or ints; bools, str, None fail here
                if type(t) in _NUM and type(ug) in _NUM and type(x1) in _NUM and type(x3) in _NUM and \
                        type(x4) in _NUM and type(x5) in _NUM and math.isfinite(t + ug + x1 + x3 + x4 + x5):
                    return (seq, float(t), float(ug), float(x1), float(x3), float(x4), float(x5))
            except OverflowError:  # huge ints
                pass
    if not isinstance(obj, dict):
        raise Rejected("wrong-type", f"payload is a JSON {type(obj).__name__}, not an object")
    try:
        s = Sample.model_validate(obj)
    except ValidationError as exc:
        raise Rejected(*_classify(exc, obj)) from None
    return (s.seq, s.t, s.ug, s.x1, s.x3, s.x4, s.x5)  # pragma: no cover (fast path takes these)


def parse_config(obj) -> RigConfig:
    """A decoded config payload validated as ``contract.RigConfig``."""
    if not isinstance(obj, dict):
        raise Rejected("wrong-type", f"payload is a JSON {type(obj).__name__}, not an object")
    for k, v in obj.items():
        if isinstance(v, float) and not math.isfinite(v) or _nonfinite_string(v):
            raise Rejected("non-finite", k)
    try:
        return RigConfig.model_validate(obj)
    except ValidationError as exc:
        raise Rejected(*_classify(exc, obj)) from None


@dataclass
class _Rig:
    row: int
    config: RigConfig | None
    last_seq: int = -1
    n: int = 0                # samples since the estimates (re)started = Fleet.counts[row]
    since_gap: int = -1       # samples after the last gap sample; -1 = no gap pending
    bad_input: bool = False   # a message on the sample key was rejected since the last health
    phase: int = 0            # evaluation phase (Fleet.phase[row])


class MonitorCore:
    """The monitor without the bus: ``process(messages) -> [(health_key, payload)]``.

    Parameters
    ----------
    namespace : str
        Key prefix of the contract.
    sample_rate : float
        Sample rate of every rig [Hz]; a config with another rate is rejected (bad-value).
    eval_every : int
        A health message every this many samples of a rig (10 at 100 Hz = 10 Hz).
    stagger : bool
        Spread the rigs' health messages over the window (``monitor.pipeline.eval_phase``: rig
        ``id`` reports after the samples where its count + phase is a multiple of eval_every)
        so a fleet's grading and publishing load is even from tick to tick (measured at 1000
        rigs: all evaluating on one tick cost the monitor ~30 ms in a burst every 100 ms).
    stale_samples : int or None
        Samples after a gap during which health says ``stale`` (default eval_every).
    on_reject : callable or None
        Called as ``on_reject(reason, key, detail)`` for every rejected message (logging).
    **fleet_kw
        ``monitor.pipeline.Fleet`` hyperparameters (options, ranges, grade_z, grade_margin).
    """

    def __init__(self, namespace: str = DEFAULT_NAMESPACE, *, sample_rate: float = 100.0,
                 eval_every: int = 10, stale_samples: int | None = None, stagger: bool = True,
                 on_reject: Callable[[str, str, str], None] | None = None, **fleet_kw):
        self.namespace = _check_ns(namespace)
        self.eval_every = int(eval_every)
        self.stale_samples = self.eval_every if stale_samples is None else int(stale_samples)
        if self.stale_samples < 0:
            raise ValueError(f"stale_samples {stale_samples!r} must be >= 0")
        self.fleet = Fleet(sample_rate=sample_rate, eval_every=eval_every, stagger=stagger, **fleet_kw)
        self.on_reject = on_reject
        self.counters = MonitorCounters()
        self.rigs: dict[str, _Rig] = {}
        self.configs: dict[str, RigConfig] = {}   # latest valid config per rig id
        self.latest: dict[str, bytes] = {}        # latest health payload per rig id
        self._prefix = f"{namespace}/rig/"
        self._graded = self.fleet.graded
        self._health_keys: dict[str, str] = {}
        self._early_bad: set[str] = set()  # rigs with a rejected sample before their first good one
        self._known: dict[str, _Rig] = {}  # sample key -> its rig, for keys already validated
        self._clear()

    # -- batch of accepted samples --------------------------------------------------------
    def _clear(self) -> None:
        self._b_rows: list[int] = []
        self._b_vals: list[tuple] = []  # (seq, t, ug, x1, x3, x4, x5) per accepted sample
        self._b_status: dict[int, str] = {}  # batch index -> status, where a window ends abnormally

    def _flush(self, out: list) -> None:
        if not self._b_rows:
            return
        rows = np.array(self._b_rows, dtype=np.int64)
        vals = self._b_vals
        ev = self.fleet.update(rows, np.array(vals, dtype=np.float64)[:, 2:])
        ids = self.fleet.ids
        status = self._b_status
        for j in range(len(ev)):
            i = int(ev.sample[j])
            rig_id = ids[int(ev.rig[j])]
            payload = self._health_payload(j, ev, vals[i][0], vals[i][1], status.get(i))
            self.latest[rig_id] = payload
            out.append((self._health_keys[rig_id], payload))
        self.counters.health += len(ev)
        self._clear()

    def _health_payload(self, j: int, ev, seq: int, t: float, status: str) -> bytes:
        level = int(ev.level[j])
        conv = bool(ev.converged[j])
        if status is None:
            status = "ok" if conv and level >= 0 else "converging"
        conf = float(ev.confidence[j])
        conf = min(1.0, max(0.0, conf)) if math.isfinite(conf) else 0.0
        p, s = ev.params[j].tolist(), ev.std_errors[j].tolist()
        return orjson.dumps({
            "seq": seq, "t": t,
            "grade": GRADES[level] if level >= 0 else "unknown",
            "level": level if level >= 0 else None,
            "confidence": conf,
            "params": {k: v for k, v in zip(PARAM_NAMES, p) if math.isfinite(v)},
            "param_grades": {k: (GRADES[g] if g >= 0 else "unknown")
                             for k, g in zip(self._graded, ev.grades[j].tolist())},
            "status": status,
            "std_errors": {k: v for k, v in zip(PARAM_NAMES, s) if math.isfinite(v)},
        })

    # -- input ----------------------------------------------------------------------------
    def _reject(self, reason: str, key: str, detail: str, rig: _Rig | None = None) -> None:
        self.counters.rejected[reason] += 1
        if rig is not None:
            rig.bad_input = True
        if self.on_reject is not None:
            self.on_reject(reason, key, detail)

    def _rig(self, rig_id: str) -> _Rig:
        rig = self.rigs.get(rig_id)
        if rig is None:
            config = self.configs.get(rig_id)
            row = self.fleet.add_rig(rig_id, config)
            rig = self.rigs[rig_id] = _Rig(row, config, phase=int(self.fleet.phase[row]))
            self._health_keys[rig_id] = health_key(rig_id, self.namespace)
        return rig

    def _on_config(self, rig_id: str, key: str, payload: bytes, out: list) -> None:
        try:
            config = parse_config(decode_json(payload))
            if abs(config.sample_rate - self.fleet.sample_rate) > 1e-9:
                raise Rejected("bad-value", f"sample_rate {config.sample_rate} Hz; this monitor runs "
                                            f"at {self.fleet.sample_rate} Hz")
        except Rejected as exc:
            self._reject(exc.reason, key, exc.detail)
            return
        self.counters.configs += 1
        self.configs[rig_id] = config
        rig = self.rigs.get(rig_id)
        if rig is None or rig.config == config or (rig.config is None and config == RigConfig()):
            if rig is not None:
                rig.config = config
            return
        self._flush(out)  # the samples before the change belong to the old constants
        self.fleet.set_config(rig.row, config)
        rig.config, rig.n, rig.since_gap = config, 0, -1
        self.counters.config_changes += 1

    def _on_sample(self, rig_id: str, key: str, payload: bytes, out: list) -> None:
        try:
            vals = parse_sample(decode_json(payload))
        except Rejected as exc:
            self._reject(exc.reason, key, exc.detail, self.rigs.get(rig_id))
            if rig_id not in self.rigs:  # remember it for the rig's first health
                self._early_bad.add(rig_id)
            return
        rig = self._rig(rig_id)
        self._known[key] = rig
        if rig_id in self._early_bad:
            self._early_bad.discard(rig_id)
            rig.bad_input = True
        self._take(rig, vals, out)

    def _on_known_sample(self, rig: _Rig, key: str, payload: bytes, out: list) -> None:
        try:
            vals = parse_sample(decode_json(payload))
        except Rejected as exc:
            self._reject(exc.reason, key, exc.detail, rig)
            return
        self._take(rig, vals, out)

    def _take(self, rig: _Rig, vals: tuple, out: list) -> None:
        """Sequence checks of a valid sample of a known rig, then into the batch."""
        seq = vals[0]
        if rig.last_seq >= 0 and seq <= rig.last_seq:
            if seq == 0 and rig.last_seq > 0:  # the rig restarted (or a replay looped): start afresh
                self._flush(out)
                self.fleet.reset(rig.row)
                rig.n, rig.since_gap = 0, -1
                self.counters.restarts += 1
            elif seq == rig.last_seq:
                self.counters.duplicate += 1
                return
            else:
                self.counters.out_of_order += 1
                return
        elif rig.last_seq >= 0 and seq > rig.last_seq + 1:
            self._flush(out)  # the filters restart between the rig's old and new samples
            self.fleet.reset_signals(rig.row)
            self.counters.gaps += 1
            self.counters.missing += seq - rig.last_seq - 1
            rig.since_gap = 0
        elif rig.since_gap >= 0:
            rig.since_gap += 1
        rig.last_seq = seq
        rig.n += 1
        self.counters.accepted += 1
        status = None
        if (rig.n + rig.phase) % self.eval_every == 0:  # this sample ends an evaluation window
            if rig.bad_input:
                status = "bad-input"
            elif 0 <= rig.since_gap < self.stale_samples:
                status = "stale"
            if rig.since_gap >= self.stale_samples:
                rig.since_gap = -1
            rig.bad_input = False
        if status is not None:
            self._b_status[len(self._b_rows)] = status
        self._b_rows.append(rig.row)
        self._b_vals.append(vals)

    def process(self, messages: Iterable[tuple[str, bytes]]) -> list[tuple[str, bytes]]:
        """Consume messages ``(key, payload bytes)`` in order; return the health messages
        ``(key, JSON bytes)`` they produce, in order. Never raises on bad input."""
        out: list[tuple[str, bytes]] = []
        prefix = self._prefix
        known = self._known
        for key, payload in messages:
            rig = known.get(key)
            if rig is not None:  # the sample key of a rig seen before: validated then
                try:
                    vals = parse_sample(orjson.loads(payload))
                except (orjson.JSONDecodeError, Rejected):  # the slow path says why
                    self._on_known_sample(rig, key, payload, out)
                else:
                    self._take(rig, vals, out)
                continue
            if not key.startswith(prefix):
                self._reject("bad-key", key, f"not under {prefix}")
                continue
            parts = key[len(prefix):].split("/")
            if len(parts) != 2 or parts[1] not in ("sample", "config", "health"):
                self._reject("bad-key", key, "expected <ns>/rig/<id>/sample or config")
                continue
            rig_id, leaf = parts
            if leaf == "health":
                self.counters.ignored += 1
                continue
            if not valid_rig_id(rig_id):
                self._reject("bad-rig-id", key, f"{rig_id[:80]!r} is not 1-64 chars of [A-Za-z0-9_-]")
                continue
            if leaf == "sample":
                self._on_sample(rig_id, key, payload, out)
            else:
                self._on_config(rig_id, key, payload, out)
        self._flush(out)
        return out


class RateLimitedLog:
    """``__call__(reason, key, detail)`` logs the first rejection of each reason at once,
    then at most one line per reason every ``interval`` [s] with how many were suppressed."""

    def __init__(self, logger: logging.Logger = log, interval: float = 5.0, clock=time.monotonic):
        self.logger, self.interval, self.clock = logger, float(interval), clock
        self._last: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}

    def __call__(self, reason: str, key: str, detail: str) -> None:
        now = self.clock()
        last = self._last.get(reason)
        if last is not None and now - last < self.interval:
            self._suppressed[reason] = self._suppressed.get(reason, 0) + 1
            return
        n = self._suppressed.pop(reason, 0)
        self._last[reason] = now
        more = f" (+{n} more since the last report)" if n else ""
        self.logger.warning("rejected %s on %s: %s%s", reason, key[:200], detail[:200], more)


_RIG_PATTERN_RE = re.compile(r"\*|\$\*|[A-Za-z0-9_$*-]{1,64}")


def rig_pattern(pattern: str) -> str:
    """Validate a rig-id key-expression chunk (``*``, ``line1-*``, ``a$*b``) for sharding."""
    if not isinstance(pattern, str) or not _RIG_PATTERN_RE.fullmatch(pattern) or "**" in pattern:
        raise ValueError(f"rig pattern {pattern!r}: one key-expression chunk of [A-Za-z0-9_-], '*' or '$*'")
    if pattern != "*" and "*" in pattern:
        pattern = re.sub(r"(?<!\$)\*", "$*", pattern)  # inside a chunk zenoh spells the wildcard $*
    try:
        zenoh.KeyExpr(f"x/{pattern}")
    except Exception as exc:  # zenoh's own verdict on the expression
        raise ValueError(f"rig pattern {pattern!r}: {exc}") from None
    return pattern


def run_monitor(session: zenoh.Session, *, namespace: str = DEFAULT_NAMESPACE, node_name: str = "monitor",
                stop_event: threading.Event | None = None, duration: float | None = None,
                core: MonitorCore | None = None, capacity: int = 65536, max_batch: int = 20000,
                poll_s: float = 0.005, on_health: Callable[[str, bytes], None] | None = None,
                congestion: zenoh.CongestionControl = zenoh.CongestionControl.BLOCK,
                config_query_s: float = 5.0, clock=time.monotonic, rigs: str = "*") -> MonitorCore:
    """Run the monitor node on an open session until ``stop_event`` is set or ``duration`` [s].

    Parameters
    ----------
    session : zenoh.Session
        An open session (not closed here).
    node_name : str
        Name of the liveliness token ``<ns>/monitor/<node_name>``.
    core : MonitorCore or None
        The core to run (default: a fresh one with a rate-limited rejection log).
    capacity : int
        Messages each FIFO channel holds before zenoh back-pressures the transport.
    max_batch : int
        Most messages drained into one batch.
    poll_s : float
        Wait after each drained batch [s]: arrivals accumulate into the next batch (adds at
        most this much latency; saves the fixed cost of many tiny batches).
    on_health : callable or None
        Called with ``(key, payload)`` of each health message after it is published.
    rigs : str
        Which rigs this monitor grades: one key-expression chunk matched against the rig id
        (``*`` all, ``line1-*`` a prefix, ``$*`` wildcards inside a chunk). Several monitors with
        disjoint patterns shard a plant: each rig's state lives in exactly one of them.
    config_query_s : float
        At start, the monitor queries ``<ns>/rig/*/config`` for the configs of rigs that
        are already running; replies count as config messages for this long [s].

    Returns the core (its ``counters``, ``latest`` health per rig).
    """
    _check_ns(namespace)
    core = core or MonitorCore(namespace, on_reject=RateLimitedLog())
    if core.namespace != namespace:
        raise ValueError(f"core namespace {core.namespace!r} != {namespace!r}")
    warm_up()  # compile before subscribing: the first samples must not queue behind the compiler
    stop = stop_event if stop_event is not None else threading.Event()
    deadline = None if duration is None else clock() + duration

    def answer(query: zenoh.Query) -> None:
        qk = query.key_expr
        for rig_id, payload in list(core.latest.items()):
            key = health_key(rig_id, namespace)
            if qk.intersects(zenoh.KeyExpr(key)):
                query.reply(key, payload, encoding=JSON)

    def publish(items) -> None:
        # session.put, not a declared publisher per rig: every declared key expression is a
        # resource in this session's routing tables, and zenoh matches each incoming sample's key
        # against them (measured: 300 health publishers put the receive thread at 99 % of a core
        # for 30k samples/s; without them, 12 %)
        put = session.put
        for key, payload in items:
            put(key, payload, encoding=JSON, congestion_control=congestion)
            if on_health is not None:
                on_health(key, payload)

    rig_chunk = rig_pattern(rigs)
    sub_c = session.declare_subscriber(f"{namespace}/rig/{rig_chunk}/config", zenoh.handlers.FifoChannel(capacity))
    sub_s = session.declare_subscriber(f"{namespace}/rig/{rig_chunk}/sample", zenoh.handlers.FifoChannel(capacity))
    queryable = session.declare_queryable(f"{namespace}/rig/*/health", answer)
    # last: a peer that sees the token has seen the subscribers declared before it
    token = session.liveliness().declare_token(liveliness_key(node_name, namespace))

    # rigs that published their config before we came up: ask their nodes (the sim node
    # answers on <ns>/rig/*/config); replies are handled as config messages
    replies = session.get(f"{namespace}/rig/{rig_chunk}/config", zenoh.handlers.FifoChannel(4096),
                          timeout=config_query_s)
    replies_until = clock() + config_query_s + 1.0

    def drain() -> int:
        nonlocal replies
        batch = []
        if replies is not None:
            try:
                while (r := replies.try_recv()) is not None:
                    if r.ok is not None:
                        batch.append((str(r.ok.key_expr), r.ok.payload.to_bytes()))
            except zenoh.ZError:  # the query is over (zenoh closes the reply channel)
                replies = None
            if clock() > replies_until:
                replies = None
        # configs first: a config queued with samples applies to them
        while len(batch) < max_batch and (m := sub_c.try_recv()) is not None:
            batch.append((str(m.key_expr), m.payload.to_bytes()))
        while len(batch) < max_batch and (m := sub_s.try_recv()) is not None:
            batch.append((str(m.key_expr), m.payload.to_bytes()))
        if batch:
            publish(core.process(batch))
        return len(batch)

    quiet = QuietGC()
    quiet.__enter__()  # left in the finally below
    try:
        while True:
            started = time.perf_counter()
            n = drain()
            if stop.is_set() or (deadline is not None and clock() >= deadline):
                break
            if n < max_batch:
                quiet.idle()  # garbage collection between batches, not inside one
                # let arrivals accumulate: one batch per poll_s amortises the per-batch cost
                # (measured: 9 samples a batch cost 36 us a sample live, against 5 us offline);
                # a batch that took longer than that is followed at once (we are behind)
                rest = poll_s - (time.perf_counter() - started)
                if rest > 0:
                    stop.wait(rest)
        for _ in range(100):  # what is already queued (bounded: a producer may still be sending)
            if drain() < max_batch:
                break
    except zenoh.ZError as exc:  # the session was closed under us
        log.warning("monitor stopping: %s", exc)
    finally:
        quiet.__exit__()
        for obj in (sub_s, sub_c, queryable, token):
            try:
                obj.undeclare()
            except zenoh.ZError:
                pass
    return core
