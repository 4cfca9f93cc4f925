"""The rig table of :class:`hydromon.engine.core.MonitorCore`: rigs coming (a row each), their
configs, forgetting them, the ranges that grade them, and the samples kept for commissioning.

A mixin: it works on the core's rows, sequence arrays and verdicts (``hydromon.engine.core``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from hydromon.contract import RigConfig, frame_key, health_key, sample_key
from hydromon.engine.validate import Rejected, decode_json, parse_config

__all__ = ["ROW_STATE", "Rig", "RigTable"]


@dataclass(eq=False)  # identity: `None in rigs` must not call a field-wise __eq__ per rig
class Rig:
    row: int
    config: RigConfig | None


# per-row sequence state of MonitorCore: (attribute, value of a row with no rig yet, dtype); one
# table for creating, growing and (after MonitorCore.forget) resetting the rows
ROW_STATE = (
    ("_last", -1, np.int64),           # last seq taken; -1 = none yet
    ("_n", 0, np.int64),               # samples since the estimates (re)started
    ("_gap", -1, np.int64),            # samples after the last gap; -1 = none pending
    ("_bad", False, np.bool_),         # a sample-key message rejected since the last health
    ("_clamp_warned", False, np.bool_),  # warned of its x1 beyond a chamber's end
    ("_back_n", 0, np.int64),          # samples in a row below the last seq (a restart?)
    ("_back_seq", -1, np.int64),       # the last of them
    ("_back_warned", False, np.bool_),  # warned of a seq going back
    ("_holding", False, np.bool_),     # samples held back by the sequence rule (in _held)
    ("_units", 0, np.int64),           # samples beyond its config's bounds since its latest evaluation
    ("_units_windows", 0, np.int64),   # evaluations that found a few beyond, since the estimates (re)started
    ("_units_warned", False, np.bool_),  # warned of them (hydromon.engine.units_watch)
    ("_refused_n", 0, np.int64),       # its messages rejected, ever (the silence watch compares)
    ("_same", 0, np.int64),            # samples in a row repeating the one before (hydromon.engine.frozen_watch)
    ("_watched", 0, np.int64),         # samples the frozen watch has seen
    ("_frozen_from", -1, np.int64),    # where the freeze last warned of began, in those samples (-1: none)
    ("_run3", 0, np.int64),            # samples in a row repeating the x3 before (hydromon.engine.stuck_watch)
    ("_run4", 0, np.int64),            # the same of x4
    ("_lo3", np.inf, np.float64),      # the spool's extremes [m] over x3's run
    ("_hi3", -np.inf, np.float64),
    ("_lo4", np.inf, np.float64),      # and over x4's
    ("_hi4", -np.inf, np.float64),
    ("_stuck_from3", -1, np.int64),    # where x3's stuck stretch last warned of began, in _watched's samples
    ("_stuck_from4", -1, np.int64),    # and x4's
)


class RigTable:
    """MonitorCore's rigs (a mixin)."""

    def tap(self, rig_id: str) -> None:
        """Keep every sample of ``rig_id`` the estimators take from now on (for :meth:`tapped`)."""
        self._taps.setdefault(self.rigs[rig_id].row, [])

    def tapped(self, rig_id: str, take: bool = False) -> np.ndarray:
        """The samples of ``rig_id`` kept since :meth:`tap`, ``(n, 6)``: t [s], ug [V], x1 [m],
        x3 [Pa], x4 [Pa], x5 [m] (the valve drive taken in), in the order taken; ``take``: stop
        keeping them."""
        rig = self.rigs.get(rig_id)
        kept = (self._taps.pop(rig.row, []) if take else self._taps.get(rig.row, [])) if rig else []
        return np.concatenate(kept) if kept else np.zeros((0, 6))

    def ranges_changed(self, rig_id: str) -> None:
        """Look up again which ranges grade ``rig_id`` (after its ranges in the book changed)."""
        rig = self.rigs.get(rig_id)
        if rig is not None:
            self.verdicts.apply(rig.row, rig.config)

    def ranges_of(self, rig_id: str):
        """``(Ranges, tag)`` the rig is graded on; ``(None, None)`` when none (or an unknown rig)."""
        rig = self.rigs.get(rig_id)
        return (None, None) if rig is None else self.verdicts.ranges_of(rig.row)

    def _refused(self, rig_id: str | None, key: str, exc, rig: Rig | None = None) -> None:
        """A sample or frame of ``rig`` (or of ``rig_id``) rejected (``exc``: ``Rejected``): counted
        and logged; a rig not seen yet has its first health say bad-input."""
        rig = rig or self.rigs.get(rig_id)
        self._reject(exc.reason, key, exc.detail, rig)
        if rig is None and len(self._early_bad) < self.max_rigs:
            self._early_bad.add(rig_id)

    def _admit(self, rig_id: str, key: str, known: dict) -> Rig | None:
        """The rig of the first valid message on ``key`` (remembered in ``known``, key -> rig), added
        if new; None when the core is full (the message refused as too-many-rigs)."""
        if rig_id not in self.rigs and len(self.rigs) >= self.max_rigs:
            self._reject("too-many-rigs", key, self._full())
            return None
        rig = known[key] = self._rig(rig_id)
        if rig_id in self._early_bad:
            self._early_bad.discard(rig_id)
            self._bad[rig.row] = True
        return rig

    def _full(self) -> str:
        return (f"this monitor holds its limit of {self.max_rigs} rigs (--max-rigs); a new rig id is refused "
                "(shard a larger plant with --rigs PATTERN)")

    def _rig(self, rig_id: str) -> Rig:
        rig = self.rigs.get(rig_id)
        if rig is None:
            config = self.configs.get(rig_id)
            row = self.fleet.add_rig(rig_id, config)  # a forgotten rig's row, or a new one
            self.verdicts.announcer.reset(row)
            if row >= len(self._last):
                grow = len(self._last)
                for name, value, dtype in ROW_STATE:
                    setattr(self, name, np.concatenate([getattr(self, name), np.full(grow, value, dtype=dtype)]))
                self._prev = np.concatenate([self._prev, np.full((grow, 5), np.nan)])
            rig = self.rigs[rig_id] = Rig(row, config)
            self._set_limits(row, config)
            if row < len(self._health_keys):
                self._health_keys[row] = health_key(rig_id, self.namespace)
            else:
                self._health_keys.append(health_key(rig_id, self.namespace))
            self._unused.pop(rig_id, None)  # its kept config is in use
            self.verdicts.apply(row, config)
        return rig

    def forget(self, rig_ids: Iterable[str]) -> list[str]:
        """Forget these rigs (silent ones: the node decides when): their estimates, latest health
        and seq state go, and their rows are reused by the next new rigs, so a plant whose rig ids
        come and go never reaches ``max_rigs`` with rigs long gone. A forgotten rig that comes back
        starts afresh, as a new rig, with the config it last sent (configs are published once and
        on change); the configs of rig ids without a row (forgotten, or never started) are kept up to
        ``max_rigs`` configs in all, the oldest dropped first. Call between :meth:`process` calls.
        Returns the ids forgotten."""
        done = []
        for rig_id in rig_ids:
            rig = self.rigs.pop(rig_id, None)
            if rig is None:
                continue
            r = rig.row
            self.fleet.remove_rig(rig_id)
            self.verdicts.forget(r)
            self._held.pop(r, None)
            self._taps.pop(r, None)
            self.latest.pop(rig_id, None)
            self._known.pop(sample_key(rig_id, self.namespace), None)
            self._frame_rigs.pop(frame_key(rig_id, self.namespace), None)
            for name, value, _ in ROW_STATE:
                getattr(self, name)[r] = value
            self._prev[r] = np.nan  # the next rig in this row repeats nothing of this one
            if rig_id in self.configs:
                self._unused[rig_id] = None
            done.append(rig_id)
        self.counters.forgotten += len(done)
        return done

    def _config_room(self) -> bool:
        """Room for one more rig's config: the oldest config of a rig id that holds no row (one
        that never sent a sample, or was forgotten) makes room. Configs of made-up rig ids that
        never send a sample must not keep a real rig's config out: it would be graded on the
        reference rig's constants."""
        if len(self.configs) < self.max_rigs:
            return True
        if self._unused:
            oldest = next(iter(self._unused))
            del self._unused[oldest], self.configs[oldest]
            self.counters.configs_dropped += 1
            return True
        return False

    def _on_config(self, rig_id: str, key: str, payload: bytes, out: list) -> None:
        try:
            config = parse_config(decode_json(payload))
            if abs(config.sample_rate - self.fleet.sample_rate) > 1e-9:
                raise Rejected("bad-value", f"sample_rate {config.sample_rate} Hz; this monitor runs "
                                            f"at {self.fleet.sample_rate} Hz")
        except Rejected as exc:
            # a rig being graded: its next health says bad-input (it is still graded on the
            # constants it had, so its health must not say ok as if nothing were wrong)
            self._reject(exc.reason, key, exc.detail, self.rigs.get(rig_id))
            return
        if rig_id not in self.configs and rig_id not in self.rigs and \
                (len(self.rigs) >= self.max_rigs or not self._config_room()):
            self._reject("too-many-rigs", key, self._full())
            return
        self.counters.configs += 1
        self.configs[rig_id] = config
        rig = self.rigs.get(rig_id)
        if rig is None:  # kept for the rig's first sample; newest last
            self._unused.pop(rig_id, None)
            self._unused[rig_id] = None
        if rig is None or rig.config == config or (rig.config is None and config == RigConfig()):
            if rig is not None:
                rig.config = config
                self._set_limits(rig.row, config)
            return
        if self.on_warning is not None:  # a restart of the estimates: the operator should see why
            old = (rig.config or RigConfig()).model_dump()
            changed = [k for k, v in config.model_dump().items() if old.get(k) != v]
            self.on_warning(rig_id, f"config changed ({', '.join(changed)}): its estimates restart with the "
                                    "new constants (a grade again after about 3 s of samples)")
        self._flush(out)  # the samples before the change belong to the old constants
        self.fleet.set_config(rig.row, config)
        self._restarted(rig.row)
        rig.config = config
        self._set_limits(rig.row, config)
        self.verdicts.apply(rig.row, config)  # ranges made for the old constants do not fit the new
        self._n[rig.row], self._gap[rig.row] = 0, -1
        self.counters.config_changes += 1

