"""The monitor without the bus: raw ``(key, payload)`` messages in, health messages out.

:class:`MonitorCore` has no clock, no threads and no I/O, so the live node
(``hydromon.monitornode``), ``hydromon replay`` over the bus and ``hydromon replay --direct``
all give the same health for the same message sequence, and tests drive it in memory.
Payloads are validated by ``hydromon.edge``.

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

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
import orjson

from hydromon.contract import DEFAULT_NAMESPACE, GRADES, PARAM_NAMES, RigConfig, _check_ns, health_key, valid_rig_id
from hydromon.edge import REJECT_REASONS, Rejected, decode_json, parse_config, parse_sample
from monitor.pipeline import Fleet

__all__ = ["MonitorCore", "MonitorCounters"]


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
