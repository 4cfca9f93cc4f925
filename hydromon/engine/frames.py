"""Frames (``contract.Frame``): many consecutive samples of one rig in one message, into arrays.

:func:`frame_payload` is how ``hydromon sim --frame N`` (on the bus and into files) encodes a
frame; :func:`decode_frame` decodes one into arrays, validated as strictly as a sample: one
typed decode in C (msgspec: JSON straight into the seven typed fields, unknown fields, bools,
strings, NaN, Infinity and overflowing numbers refused) and a few array checks (lengths,
``SEQ_MAX``, ``hydromon.engine.validate.VALUE_LIMITS``, increasing times). A payload the fast
path does not take goes to ``hydromon.engine.validate.parse_frame`` (the contract model), which
accepts it or rejects it with the reason a sample would get.

The encoding, JSON arrays of numbers per channel, was chosen by measurement
(``python -m hydromon.tools.bench.frame_codec``, docs/performance.md): it decodes about as fast as
alternatives that JSON tools cannot plot (base64 of float64 arrays) at 10 samples a frame, and
Foxglove and other JSON Schema readers show it as it is.

:class:`FrameInput` is the monitor core's entry for frames (a mixin of
``hydromon.engine.core.MonitorCore``): a frame of a rig with nothing pending whose first seq
follows the rig's last goes into the batch as one array (no Python object per sample);
anything else is taken sample by sample through the core's sequence rule, exactly as the same
samples sent one per message.
"""

from __future__ import annotations

import msgspec
import numpy as np
import orjson

from hydromon.contract import DRIVE_LIMIT, FRAME_MAX, SAMPLE_COLUMNS, SEQ_MAX, frame_key
from hydromon.engine.validate import VALUE_LIMITS, Rejected, decode_json, parse_frame

__all__ = ["frame_payload", "block_frames", "decode_frame", "frame_samples", "FrameInput"]


def frame_payload(seq: int, t: list, columns: list, u: list | None = None) -> bytes:
    """JSON of a frame: first ``seq``, times ``t`` [s] and ``columns`` = the lists of ug [V], x1 [m],
    x3, x4 [Pa], x5 [m], one value per sample; with ``u``, each sample's valve drive [V]."""
    ug, x1, x3, x4, x5 = columns
    obj = {"seq": seq, "t": t, "ug": ug, "x1": x1, "x3": x3, "x4": x4, "x5": x5}
    if u is not None:
        obj["u"] = u
    return orjson.dumps(obj)


# the contract's frame fields, typed (msgspec takes an int for a float, as the model does)
_FrameStruct = msgspec.defstruct(
    "_FrameStruct", [("seq", int), *((name, list[float]) for name in SAMPLE_COLUMNS), ("u", list[float] | None, None)],
    forbid_unknown_fields=True)
_DECODE = msgspec.json.Decoder(_FrameStruct).decode


_LIMITS = VALUE_LIMITS[:, None]  # |ug|, |x1|, |x3|, |x4|, |x5| limits as a column


def _arrays(seq: int, t, ug, x1, x3, x4, x5, u):
    """``(seq, vals, u)`` if the columns make a valid frame, else None (the model says why)."""
    n = len(t)
    if not (1 <= n <= FRAME_MAX and len(ug) == n and len(x1) == n and len(x3) == n and len(x4) == n
            and len(x5) == n and 0 <= seq and seq + n - 1 <= SEQ_MAX):
        return None
    cols = np.array((t, ug, x1, x3, x4, x5), dtype=np.float64)  # (6, n)
    # the times compared in Python: on a list of 10, faster than two more array operations
    if not (np.abs(cols[1:]) <= _LIMITS).all() or not all(map(float.__lt__, t, t[1:])):
        return None
    vals = cols.T  # (n, 6): t, ug, x1, x3, x4, x5
    if u is not None:
        if len(u) != n:
            return None
        u = np.array(u, dtype=np.float64)
        if not (np.abs(u) <= DRIVE_LIMIT).all():
            return None
    return seq, vals, u


def decode_frame(payload: bytes) -> tuple[int, np.ndarray, np.ndarray | None]:
    """``(seq, vals, u)`` of a frame payload: its first seq, ``vals`` float64 ``(n, 6)`` with columns
    t [s], ug [V], x1 [m], x3, x4 [Pa], x5 [m], and ``u`` float64 ``(n,)`` [V] or None. Raises
    ``Rejected`` with a sample's reasons (``hydromon.engine.validate``)."""
    try:
        f = _DECODE(payload)
    except msgspec.DecodeError:
        f = None
    if f is not None:
        got = _arrays(f.seq, f.t, f.ug, f.x1, f.x3, f.x4, f.x5, f.u)
        if got is not None:
            return got
    fr = parse_frame(decode_json(payload))  # raises with the reason
    got = _arrays(fr.seq, fr.t, fr.ug, fr.x1, fr.x3, fr.x4, fr.x5, fr.u)
    if got is None:  # pragma: no cover - the model and the array checks are the same rules
        raise Rejected("bad-value", "frame refused by the array checks")
    return got


def frame_samples(seq: int, vals: np.ndarray, u: np.ndarray | None) -> list[tuple]:
    """The frame's samples as the tuples ``validate.parse_sample`` gives: ``(seq, t, ug, x1, x3, x4,
    x5)``, with ``u`` [V] as an eighth value when the frame carries the drive."""
    rows = vals.tolist()
    if u is None:
        return [(seq + i, *row) for i, row in enumerate(rows)]
    return [(seq + i, *row, d) for i, (row, d) in enumerate(zip(rows, u.tolist()))]


class FrameInput:
    """MonitorCore's frame path (a mixin: it works on the core's rig table and sequence arrays).

    The core keeps ``_frame_rigs`` (frame key -> its rig, for keys already validated) and calls
    :meth:`_on_frame` for every message on a rig's frame key, in arrival order.
    """

    def sends_frames(self, rig_id: str) -> bool:
        """Has the rig sent a valid frame (its frame key is known)?"""
        return rig_id in self.rigs and frame_key(rig_id, self.namespace) in self._frame_rigs

    def _on_frame(self, key: str, payload: bytes, out: list, rig=None, rig_id: str | None = None) -> None:
        """One frame message of the rig ``rig`` (a known frame key), or of ``rig_id`` (a first)."""
        try:
            seq, vals, u = decode_frame(payload)
        except Rejected as exc:
            self._reject(exc.reason, key, exc.detail, rig or self.rigs.get(rig_id))
            if rig is None and rig_id not in self.rigs and len(self._early_bad) < self.max_rigs:
                self._early_bad.add(rig_id)  # for the rig's first health
            return
        if rig is None:
            if rig_id not in self.rigs and len(self.rigs) >= self.max_rigs:
                self._reject("too-many-rigs", key, self._full())
                return
            rig = self._rig(rig_id)
            self._frame_rigs[key] = rig
            if rig_id in self._early_bad:
                self._early_bad.discard(rig_id)
                self._bad[rig.row] = True
        r, n = rig.row, len(vals)
        last = int(self._last[r])
        if u is None and last >= 0 and seq == last + 1 and self._gap[r] < 0 and not self._bad[r] \
                and self._back_n[r] == 0 and not self._holding[r]:
            # RegularBatch._take_regular for one rig's run of n samples: no window of theirs ends
            # abnormally (the scalar updates of one row, not the fancy-indexed ones of many rigs)
            self._seal()
            self._chunks.append((np.full(n, r, dtype=np.int64), vals))
            self._b_seqs.extend(range(seq, seq + n))
            self._b_msg.extend([self._cur] * n)
            self._last[r] = seq + n - 1
            self._n[r] += n
            self.counters.accepted += n
            return
        for sample in frame_samples(seq, vals, u):  # the sequence rule, sample by sample
            self._take(r, sample, out)


def block_frames(blk, j0: int, j1: int, with_u=frozenset()) -> list[bytes]:
    """Frame payloads of the samples ``j0 .. j1 - 1`` of a ``plant_sim.live.Block`` (every rig's
    samples ``(n_rigs, k, 5)``, its ``seq``, ``t`` [s] and valve drive ``u``), one per rig in rig
    order; rigs whose index is in ``with_u`` carry the drive [V]."""
    seq, t = int(blk.seq[j0]), blk.t[j0:j1].tolist()
    columns = blk.samples[:, j0:j1, :].transpose(0, 2, 1).tolist()  # (n_rigs, 5, n)
    if not with_u:
        return [frame_payload(seq, t, c) for c in columns]
    us = blk.u[:, j0:j1].tolist()
    return [frame_payload(seq, t, c, us[r] if r in with_u else None) for r, c in enumerate(columns)]
