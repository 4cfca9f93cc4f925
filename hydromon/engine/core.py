"""The monitor without the bus: raw ``(key, payload)`` messages in, health messages out.

:class:`MonitorCore` has no clock, no threads and no I/O, so the live node
(``hydromon.bus.monitor``), ``hydromon replay`` over the bus and ``hydromon replay --direct``
all give the same health for the same message sequence, and tests drive it in memory. Payloads
are validated by ``hydromon.engine.validate``; each rig's sequence numbers follow
``hydromon.engine.sequence`` (a gap restarts the rig's filters, a restart its estimates); the
status of a verdict is ``hydromon.engine.status``'s. A batch's regular samples take a faster
path with the same result (``hydromon.engine.batch``).

``<ns>/rig/<id>/health`` and ``.../event`` keys are the monitors' own output (recordings hold
them): they are skipped and counted as ``ignored``, not rejected. A rejected config leaves the
rig graded on the constants it had (its next health says ``bad-input``); a rig whose x1 went
beyond a chamber's end since its estimates (re)started says ``bad-input`` too
(``X1_CLAMPED_WARNING``; the grade stays), and so does one whose readings keep breaking its
config's bounds (a channel in other units: ``hydromon.engine.units_watch``). The first health
after a gap, and every one until ``stale_samples`` (default ``eval_every``) samples have
followed it, says ``stale``; so does the latest health re-sent by :meth:`MonitorCore.stale` for
a rig that went silent (the node decides when: ``hydromon.engine.watches.SilenceWatch``).

Health payloads carry finite numbers only (JSON has no NaN/inf): a parameter whose estimate or
standard error is not finite (an equation without enough rows has infinite standard errors) is
left out of ``params`` / ``std_errors``; confidence is clipped to [0, 1] (0 if not finite).
``seq`` and ``t`` are those of the sample after which the rig was evaluated; ``level`` is null
and ``grade`` ``"unknown"`` when the level is -1.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from operator import attrgetter, itemgetter

import numpy as np
import orjson

from hydromon.contract import DEFAULT_NAMESPACE, RESTART_RUN, RigConfig, check_namespace, split_rig_key
from hydromon.engine.batch import RegularBatch
from hydromon.engine.counters import MonitorCounters
from hydromon.engine.frame_batch import FrameBatch
from hydromon.engine.frames import FrameInput
from hydromon.engine.frozen_watch import FrozenWatch
from hydromon.engine.stuck_watch import StuckWatch
from hydromon.engine.ranges_book import RangesBook
from hydromon.engine.rig_table import ROW_STATE, Rig, RigTable
from hydromon.engine.sequence import AHEAD, DUPLICATE, GAP, RESTART, SeqState, sequence_push
from hydromon.engine.units_watch import UnitsWatch
from hydromon.engine.validate import Rejected, decode_json, parse_sample, too_large_words
from hydromon.engine.verdicts import Verdicts
from monitor.drive import command_for_drive
from monitor.pipeline import Fleet

__all__ = ["X1_CLAMPED_WARNING", "MonitorCore"]


X1_CLAMPED_WARNING = ("x1 went beyond a chamber's end: the rig constants (A1, A2, V10, V20) or x1's zero, "
                      "sign or unit are wrong; its chamber parameters are not to be trusted")


_ROW = attrgetter("row")
_SEQ = _KEY = _FIRST = itemgetter(0)
_PAYLOAD = itemgetter(1)


class MonitorCore(RegularBatch, FrameBatch, RigTable, FrameInput, UnitsWatch, FrozenWatch, StuckWatch):
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
        Spread the rigs' health messages over the window (``monitor.evaluations.eval_phase``: rig
        ``id`` reports after the samples where its count + phase is a multiple of eval_every)
        so a fleet's grading and publishing load is even from tick to tick (measured at 1000
        rigs: all evaluating on one tick cost the monitor ~30 ms in a burst every 100 ms).
    stale_samples : int or None
        Samples after a gap during which health says ``stale`` (default eval_every).
    max_rigs : int
        Most rigs this core holds (about 5 kB each): a valid sample or config of a further rig
        id is rejected (``too-many-rigs``), so bogus ids on a shared bus cannot grow the monitor
        without bound (20,000 of them would add about 100 MB). Shard a larger plant.
    on_reject : callable or None
        Called as ``on_reject(reason, key, detail)`` for every rejected message (logging).
    on_warning : callable or None
        Called as ``on_warning(rig_id, message)`` when a rig's x1 first goes beyond a chamber's
        end (the rig constants or x1 are wrong, so its chamber parameters are not to be
        trusted); again if it does after a config change or a restart (seq back to 0)
        restarted the rig's estimates.
    book : RangesBook or None
        Which health ranges grade which rig (default: ``ranges`` of ``fleet_kw``, else the
        default ranges, for the rigs they were made for; ``hydromon.engine.ranges_book``).
    node, epoch : str, int or None
        The monitor node's name and start count, written into every health and event (None: left out).
    **fleet_kw
        ``monitor.pipeline.Fleet`` hyperparameters (options, ranges, grade_z, grade_margin).
    """

    SAMPLE_RATE = 100.0  # [Hz] the default: the bus contract's rigs sample at 100 Hz

    def __init__(self, namespace: str = DEFAULT_NAMESPACE, *, sample_rate: float = SAMPLE_RATE,
                 eval_every: int = 10, stale_samples: int | None = None, stagger: bool = True,
                 max_rigs: int = 10000, on_reject: Callable[[str, str, str], None] | None = None,
                 on_warning: Callable[[str, str], None] | None = None, book: RangesBook | None = None,
                 node: str | None = None, epoch: int | None = None, **fleet_kw):
        self.namespace = check_namespace(namespace)
        self.eval_every = int(eval_every)
        if self.eval_every < 1:
            raise ValueError(f"eval_every {eval_every!r} must be >= 1")
        self.stale_samples = self.eval_every if stale_samples is None else int(stale_samples)
        if self.stale_samples < 0:
            raise ValueError(f"stale_samples {stale_samples!r} must be >= 0")
        if isinstance(max_rigs, bool) or not isinstance(max_rigs, int) or max_rigs < 1:
            raise ValueError(f"max_rigs {max_rigs!r} must be an integer >= 1")
        self.max_rigs = max_rigs
        self.fleet = Fleet(sample_rate=sample_rate, eval_every=eval_every, stagger=stagger, **fleet_kw)
        self.on_reject = on_reject
        self.on_warning = on_warning
        self.counters = MonitorCounters()
        self.rigs: dict[str, Rig] = {}
        self.configs: dict[str, RigConfig] = {}   # latest valid config per rig id
        self.latest: dict[str, bytes] = {}        # latest health payload per rig id
        self.verdicts = Verdicts(self.fleet, self.namespace, book, node, epoch, on_warning)
        self._health_keys: list[str] = []          # per row
        self._early_bad: set[str] = set()  # rigs with a rejected sample before their first good one
        self._known: dict[str, Rig] = {}  # sample key -> its rig, for keys already validated
        self._frame_rigs: dict[str, Rig] = {}  # frame key -> its rig (hydromon.engine.frames)
        # configs of rig ids that hold no row (sent before the rig's first sample, or of a forgotten
        # rig), oldest first: the first to go when configs would pass max_rigs
        self._unused: dict[str, None] = {}
        self._cur = 0  # index in the current process() call of the message being taken one by one
        self._held: dict[int, SeqState] = {}  # by row: a rig's sequence state while it holds samples back
        self._taps: dict[int, list[np.ndarray]] = {}  # by row: the samples taken, kept for commissioning
        # sequence state per row (arrays, so a batch of regular samples is checked at once)
        for name, value, dtype in ROW_STATE:
            setattr(self, name, np.full(16, value, dtype=dtype))
        # each row's bounds, set with its rig, and the tightest of them (hydromon.engine.units_watch)
        self._limits, self._units_live = np.zeros((0, 4)), False
        self._prev = np.full((len(self._last), 5), np.nan)  # each row's last sample (frozen_watch); rows as ROW_STATE's
        self._tight = np.array([np.inf, np.inf, np.inf, -np.inf])
        self._clear()

    # -- batch of accepted samples --------------------------------------------------------
    def _clear(self) -> None:
        self._chunks: list[tuple[np.ndarray, np.ndarray]] = []  # (rows (m,), t..x5 (m, 6)) in order
        self._p_rows: list[int] = []    # samples taken one by one, not yet in a chunk
        self._p_vals: list[tuple] = []
        self._b_seqs: list[int] = []    # seq of every sample of the batch
        self._b_msg: list[int] = []     # its message's index in the process() call (output order)
        self._b_status: dict[int, str] = {}  # batch index -> status, where a window ends abnormally

    def _seal(self) -> None:
        if self._p_rows:
            self._chunks.append((np.array(self._p_rows, dtype=np.int64),
                                 np.array(self._p_vals, dtype=np.float64)[:, 1:]))
            self._p_rows, self._p_vals = [], []

    def _flush(self, out: list) -> None:
        self._seal()
        if not self._chunks:
            return
        if len(self._chunks) == 1:
            rows, vals = self._chunks[0]
        else:
            rows = np.concatenate([c[0] for c in self._chunks])
            vals = np.concatenate([c[1] for c in self._chunks])
        if self._taps:
            for r, kept in self._taps.items():
                mine = rows == r
                if mine.any():
                    kept.append(vals[mine])
        ev = self.fleet.update(rows, vals[:, 1:])
        self._units_flagged(rows, vals, ev)
        self._stuck_flagged(rows, vals, ev)  # before the frozen watch, which moves each row's last sample on
        self._frozen_flagged(rows, vals, ev)
        if len(ev):
            self._health(ev, vals[:, 0], out)
        self._clear()
        if self.on_warning is not None:
            self._warn_clamped()

    def _warn_clamped(self) -> None:
        clamped = self.fleet.x1_clamped_all() > 0
        warned = self._clamp_warned[:len(clamped)]
        new = clamped & ~warned
        warned |= new
        for r in np.flatnonzero(new).tolist():
            self.on_warning(self.fleet.ids[r], X1_CLAMPED_WARNING)

    def _restarted(self, r: int) -> None:
        """Row r's estimates restarted (config change, seq restart): warn of it afresh."""
        self._clamp_warned[r] = False
        self._units[r], self._units_windows[r], self._units_warned[r] = 0, 0, False
        self._back_n[r] = 0
        self._back_warned[r] = False

    def _health(self, ev, t: np.ndarray, out: list) -> None:
        """Health payloads of a batch's evaluations (``hydromon.engine.verdicts``)."""
        seqs, status, msg = self._b_seqs, self._b_status, self._b_msg
        sample = ev.sample.tolist()
        flagged = [status.get(i) for i in sample] if status else [None] * len(sample)
        payloads = self.verdicts.payloads(ev, [seqs[i] for i in sample], t[ev.sample], flagged)
        ids, keys, latest = self.fleet.ids, self._health_keys, self.latest
        for i, r, payload in zip(sample, ev.rig.tolist(), payloads):
            latest[ids[r]] = payload
            out.append((msg[i], keys[r], payload))
        self.counters.health += len(ev)

    def take_events(self) -> list[tuple[str, bytes]]:
        """The grade and status changes announced since the last call, as ``(event key, payload)``
        in order (``hydromon.engine.events``); the node publishes them after the health."""
        return self.verdicts.take_events()

    def last_seqs(self) -> np.ndarray:
        """The last seq taken of each rig, by row (-1: none yet); a copy."""
        return self._last[:len(self.fleet.ids)].copy()

    def stale(self, rig_ids: Iterable[str], refused: Iterable[str] = ()) -> list[tuple[str, bytes]]:
        """The latest health of each of these rigs (silent ones: no sample taken for a while),
        re-sent with status ``stale`` (its grade and numbers are those of its last samples), or
        ``bad-input`` for the rigs of ``refused``, whose messages keep coming but are rejected
        (not silent: what they send is refused); a rig with no health yet, or whose latest says
        so already, gets none. ``latest`` says it from then on, until the rig's next health."""
        out, refused = [], set(refused)
        for rig_id in rig_ids:
            payload = self.latest.get(rig_id)
            if payload is None:
                continue
            h = orjson.loads(payload)
            row = self.rigs[rig_id].row
            status = "bad-input" if rig_id in refused else "stale"
            if h["status"] == status:
                continue
            h["status"] = status
            payload = self.latest[rig_id] = orjson.dumps(h)
            out.append((self._health_keys[row], payload))
            self.verdicts.stale(row, h["seq"], h["t"], -1 if h["level"] is None else h["level"], payload, status)
        self.counters.stale_resent += len(out)
        return out

    # -- input ----------------------------------------------------------------------------
    def _reject(self, reason: str, key: str, detail: str, rig: Rig | None = None) -> None:
        self.counters.rejected[reason] += 1
        if rig is not None:
            self._bad[rig.row] = True
            self._refused_n[rig.row] += 1
        if self.on_reject is not None:
            self.on_reject(reason, key, detail)

    def refuse_unread(self, key: str, size: int) -> None:
        """Count a message of ``size`` bytes on ``key`` that was not read (more than
        ``PAYLOAD_MAX``): rejected as ``too-large``, its rig's next health says bad-input."""
        why = Rejected("too-large", too_large_words(size))
        parts = split_rig_key(key, self.namespace)
        if isinstance(parts, str):
            self._reject(why.reason, key, why.detail)
        else:  # a rig not seen yet has its first health say bad-input
            self._refused(parts[0], key, why)

    def _on_sample(self, rig_id: str, key: str, payload: bytes, out: list) -> None:
        try:
            vals = parse_sample(decode_json(payload))
        except Rejected as exc:
            self._refused(rig_id, key, exc)
            return
        rig = self._admit(rig_id, key, self._known)
        if rig is not None:
            self._take(rig.row, vals, out)

    def _take(self, r: int, vals: tuple, out: list) -> None:
        """A valid sample of the rig in row ``r`` through its sequence rule
        (``hydromon.engine.sequence``): into the batch, held back, or dropped and counted."""
        if len(vals) == 8:  # the rig publishes its valve drive u: the identifier takes it exactly
            config = self.rigs[self.fleet.ids[r]].config or RigConfig()
            vals = (vals[0], vals[1], command_for_drive(vals[7], vals[3], config.K_p, config.K_f), *vals[3:7])
        st = self._held.pop(r, None) or SeqState(int(self._last[r]), int(self._back_n[r]), int(self._back_seq[r]))
        before = st.last
        taken, dropped = sequence_push(st, vals[0], vals)
        self._back_n[r], self._back_seq[r] = st.back_n, st.back_seq
        if st.held:
            self._held[r] = st
        self._holding[r] = bool(st.held)
        for verdict, seq, _ in dropped:
            self._drop(r, verdict, seq, before)
        for verdict, seq, tok in taken:
            self._accept(r, verdict, seq, tok, before, out)
            before = seq

    def _drop(self, r: int, verdict: int, seq: int, last: int) -> None:
        if verdict == DUPLICATE:
            self.counters.duplicate += 1
            return
        if verdict == AHEAD:
            self.counters.ahead += 1
            what = (f"seq {seq} far ahead of {last}, and no run of samples followed it: dropped (a corrupt or "
                    "forged seq?)")
        else:
            self.counters.out_of_order += 1
            what = (f"seq {seq} after {last}: dropped (out of order; two publishers under one rig id?)")
        if not self._back_warned[r] and self.on_warning is not None:
            self._back_warned[r] = True
            self.on_warning(self.fleet.ids[r], f"{what}; further ones are counted, not logged")

    def _accept(self, r: int, verdict: int, seq: int, vals: tuple, last: int, out: list) -> None:
        """A sample the sequence rule takes (``verdict`` TAKE, GAP or RESTART), after ``last``."""
        gap = int(self._gap[r])
        if verdict == RESTART:  # the rig restarted (or a replay looped): start afresh
            if seq != 0 and self.on_warning is not None:
                self.on_warning(self.fleet.ids[r], f"seq went back from {last} and ran on for {RESTART_RUN} "
                                                   f"samples (now {seq}): taken as a restart of the rig "
                                                   "whose first samples were lost")
            self._flush(out)
            self.fleet.reset(r)
            self._restarted(r)
            self._n[r], gap = 0, -1
            self.counters.restarts += 1
        elif verdict == GAP:
            self._flush(out)  # the filters restart between the rig's old and new samples
            self.fleet.reset_signals(r)
            self.counters.gaps += 1
            self.counters.missing += seq - last - 1
            gap = 0
        elif gap >= 0:
            gap += 1
        self._last[r] = seq
        n = self._n[r] = self._n[r] + 1
        self.counters.accepted += 1
        status = None
        if (n + self.fleet.phase[r]) % self.eval_every == 0:  # this sample ends an evaluation window
            if self._bad[r]:
                status = "bad-input"
            elif 0 <= gap < self.stale_samples:
                status = "stale"
            if gap >= self.stale_samples:
                gap = -1
            self._bad[r] = False
        self._gap[r] = gap
        if status is not None:
            self._b_status[len(self._b_seqs)] = status  # this sample's index in the batch
        self._p_rows.append(r)
        self._p_vals.append(vals)
        self._b_seqs.append(seq)
        self._b_msg.append(self._cur)

    def _one(self, key: str, payload: bytes, out: list) -> None:
        """One message the regular path did not take."""
        rig = self._known.get(key)
        if rig is not None:  # the sample key of a rig seen before: validated then
            try:
                vals = parse_sample(decode_json(payload))
            except Rejected as exc:
                self._reject(exc.reason, key, exc.detail, rig)
                return
            self._take(rig.row, vals, out)
            return
        rig = self._frame_rigs.get(key)
        if rig is not None:
            self._on_frame(key, payload, out, rig)
            return
        parts = split_rig_key(key, self.namespace)
        if isinstance(parts, str):
            reason, detail = parts.split(": ", 1)
            if reason == "bad-rig-id" and key.endswith(("/health", "/event")):
                self.counters.ignored += 1  # our own output kinds, whatever the id
            else:
                self._reject(reason, key, detail)
            return
        rig_id, leaf = parts
        if leaf == "sample":
            self._on_sample(rig_id, key, payload, out)
        elif leaf == "frame":
            self._on_frame(key, payload, out, rig_id=rig_id)
        elif leaf == "config":
            self._on_config(rig_id, key, payload, out)
        else:  # health and events: the monitors' own output (recordings hold them)
            self.counters.ignored += 1

    def process(self, messages: Iterable[tuple[str, bytes]]) -> list[tuple[str, bytes]]:
        """Consume messages ``(key, payload bytes)`` in order; return the health messages
        ``(key, JSON bytes)`` they produce, in the order of the samples that ended their windows
        (what taking every message one by one gives). Never raises on bad input."""
        return [(key, payload) for _, key, payload in self.process_indexed(messages)]

    def process_indexed(self, messages: Iterable[tuple[str, bytes]]) -> list[tuple[int, str, bytes]]:
        """:meth:`process`, each health message with the index in ``messages`` of the message whose
        sample ended its window: ``(index, key, JSON bytes)``, indices never decreasing."""
        out: list = []  # (message index, key, payload)
        messages = messages if isinstance(messages, list) else list(messages)
        if messages:
            if len(messages) == 1:  # a lone message: no batch to gain from
                self._cur = 0
                self._one(*messages[0], out)
            else:
                for i, key, payload in self._regular_frames(self._regular(messages)):
                    self._cur = i
                    self._one(key, payload, out)
        self._flush(out)
        out.sort(key=_FIRST)  # the regular samples were taken first: back into arrival order
        return out
