"""Frames (``contract.Frame``): many consecutive samples of one rig in one message.

:func:`frame_payload` is how ``hydromon sim --frame N`` (on the bus and into files) encodes a
frame; :func:`frame_columns` decodes one into lists of floats (:func:`decode_frame`: into
arrays), validated as strictly as a sample: one typed decode in C (msgspec: JSON straight into
the seven typed fields; unknown fields, bools, strings, NaN, Infinity and overflowing numbers
refused) and checks of the lists with builtins (lengths, ``SEQ_MAX``, the magnitude limits
``hydromon.engine.validate.VALUE_LIMITS``, strictly increasing times). A payload that fails
them goes to ``hydromon.engine.validate.parse_frame`` (the contract model), which accepts it
or rejects it with the reason a sample would get.

The encoding, JSON arrays of numbers per channel, was chosen by measurement
(``python -m hydromon.tools.bench.frame_codec``, docs/performance.md): it decodes about as fast as
base64 of float64 arrays at 10 samples a frame, and Foxglove and other JSON Schema readers show
and plot it as it is.

:class:`FrameInput` is the monitor core's entry for frames (a mixin of
``hydromon.engine.core.MonitorCore``): a frame of a rig with nothing pending whose first seq
follows the rig's last goes into the batch's open chunk of frames (lists, made into arrays once
a batch; no tuple per sample); anything else is taken sample by sample through the core's
sequence rule, exactly as the same samples sent one per message.
"""

from __future__ import annotations

import msgspec
import numpy as np
import orjson

from hydromon.contract import DRIVE_LIMIT, FRAME_MAX, SAMPLE_COLUMNS, SEQ_MAX, frame_key
from hydromon.engine.validate import VALUE_LIMITS, Rejected, decode_json, parse_frame

__all__ = ["frame_payload", "block_frames", "frame_struct", "frame_columns", "decode_frame", "frame_samples", "FrameInput"]


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
#: the typed decode of a frame payload (its fields as attributes); raises ``msgspec.DecodeError``
frame_struct = msgspec.json.Decoder(_FrameStruct).decode


_L_UG, _L_X1, _L_X3, _L_X4, _L_X5 = VALUE_LIMITS.tolist()  # |value| limits of ug, x1, x3, x4, x5


def _valid(seq: int, t: list, ug: list, x1: list, x3: list, x4: list, x5: list, u: list | None) -> bool:
    """Do the decoded columns make a valid frame (the contract's rules; the model says why not)?
    Checked on the lists with builtins: on a frame of 10, faster than making arrays to check."""
    n = len(t)
    return (1 <= n <= FRAME_MAX and len(ug) == n and len(x1) == n and len(x3) == n and len(x4) == n
            and len(x5) == n and 0 <= seq and seq + n - 1 <= SEQ_MAX
            and -_L_UG <= min(ug) and max(ug) <= _L_UG and -_L_X1 <= min(x1) and max(x1) <= _L_X1
            and -_L_X3 <= min(x3) and max(x3) <= _L_X3 and -_L_X4 <= min(x4) and max(x4) <= _L_X4
            and -_L_X5 <= min(x5) and max(x5) <= _L_X5 and all(map(float.__lt__, t, t[1:]))
            and (u is None or (len(u) == n and -DRIVE_LIMIT <= min(u) and max(u) <= DRIVE_LIMIT)))


def frame_columns(payload: bytes) -> tuple[int, tuple, list | None]:
    """``(seq, columns, u)`` of a frame payload: its first seq, the lists of t [s], ug [V], x1 [m],
    x3, x4 [Pa], x5 [m] (floats, one per sample), and the drive u [V] or None. Raises ``Rejected``
    with a sample's reasons (``hydromon.engine.validate``)."""
    try:
        f = frame_struct(payload)
    except msgspec.DecodeError:
        f = None
    if f is not None and _valid(f.seq, f.t, f.ug, f.x1, f.x3, f.x4, f.x5, f.u):
        return f.seq, (f.t, f.ug, f.x1, f.x3, f.x4, f.x5), f.u
    fr = parse_frame(decode_json(payload))  # raises with the reason
    if not _valid(fr.seq, fr.t, fr.ug, fr.x1, fr.x3, fr.x4, fr.x5, fr.u):  # pragma: no cover - the same rules
        raise Rejected("bad-value", "frame refused by the list checks")
    return fr.seq, (fr.t, fr.ug, fr.x1, fr.x3, fr.x4, fr.x5), fr.u


def decode_frame(payload: bytes) -> tuple[int, np.ndarray, np.ndarray | None]:
    """``(seq, vals, u)`` of a frame payload (:func:`frame_columns`) as arrays: ``vals`` float64
    ``(n, 6)`` with columns t [s], ug [V], x1 [m], x3, x4 [Pa], x5 [m], ``u`` float64 ``(n,)`` [V] or None."""
    seq, cols, u = frame_columns(payload)
    return seq, np.array(cols, dtype=np.float64).T, None if u is None else np.array(u, dtype=np.float64)


def frame_samples(seq: int, cols: tuple, u: list | None) -> list[tuple]:
    """The frame's samples as the tuples ``validate.parse_sample`` gives: ``(seq, t, ug, x1, x3, x4,
    x5)``, with ``u`` [V] as an eighth value when the frame carries the drive."""
    seqs = range(seq, seq + len(cols[0]))
    return list(zip(seqs, *cols) if u is None else zip(seqs, *cols, u))


class _FrameChunk:
    """Regular frames taken one after another in a batch, kept as lists and made into the
    ``(rows, vals)`` chunk of the core's batch once, when the batch is flushed: two arrays a
    batch, not two a frame."""

    __slots__ = ("rows", "cols", "_made")

    def __init__(self):
        self.rows: list[int] = []
        self.cols: tuple = ([], [], [], [], [], [])  # t, ug, x1, x3, x4, x5
        self._made = None

    def add(self, r: int, cols: tuple) -> None:
        self.rows += [r] * len(cols[0])
        t, ug, x1, x3, x4, x5 = self.cols
        t += cols[0]
        ug += cols[1]
        x1 += cols[2]
        x3 += cols[3]
        x4 += cols[4]
        x5 += cols[5]

    def _arrays(self) -> tuple[np.ndarray, np.ndarray]:
        if self._made is None:
            self._made = (np.array(self.rows, dtype=np.int64), np.array(self.cols, dtype=np.float64).T)
        return self._made

    def __getitem__(self, i: int) -> np.ndarray:
        return self._arrays()[i]

    def __iter__(self):
        return iter(self._arrays())


class FrameInput:
    """MonitorCore's frame path (a mixin: it works on the core's rig table and sequence arrays).

    The core keeps ``_frame_rigs`` (frame key -> its rig, for keys already validated) and calls
    :meth:`_on_frame` for every message on a rig's frame key, in arrival order.
    """

    _fchunk: _FrameChunk | None = None  # the batch's open chunk of regular frames

    def sends_frames(self, rig_id: str) -> bool:
        """Has the rig sent a valid frame (its frame key is known)?"""
        return rig_id in self.rigs and frame_key(rig_id, self.namespace) in self._frame_rigs

    def _on_frame(self, key: str, payload: bytes, out: list, rig=None, rig_id: str | None = None) -> None:
        """One frame message of the rig ``rig`` (a known frame key), or of ``rig_id`` (a first)."""
        try:
            seq, cols, u = frame_columns(payload)
        except Rejected as exc:
            self._refused(rig_id, key, exc, rig)
            return
        if rig is None:
            rig = self._admit(rig_id, key, self._frame_rigs)
            if rig is None:
                return
        r, n = rig.row, len(cols[0])
        last = int(self._last[r])
        if u is None and last >= 0 and seq == last + 1 and self._gap[r] < 0 and not self._bad[r] \
                and self._back_n[r] == 0 and not self._holding[r]:
            # RegularBatch._take_regular for one rig's run of n samples: no window of theirs ends
            # abnormally (the scalar updates of one row, not the fancy-indexed ones of many rigs);
            # into the batch's open frame chunk, or a new one after whatever was taken since
            chunk = self._fchunk
            if self._p_rows or not self._chunks or self._chunks[-1] is not chunk:
                self._seal()
                chunk = self._fchunk = _FrameChunk()
                self._chunks.append(chunk)
            chunk.add(r, cols)
            self._b_seqs.extend(range(seq, seq + n))
            self._b_msg.extend([self._cur] * n)
            self._last[r] = seq + n - 1
            self._n[r] += n
            self.counters.accepted += n
            return
        for sample in frame_samples(seq, cols, u):  # the sequence rule, sample by sample
            self._take(r, sample, out)


def block_frames(blk, j0: int, j1: int, with_u=frozenset(), rigs=None) -> list[bytes]:
    """Frame payloads of the samples ``j0 .. j1 - 1`` of a ``plant_sim.live.Block`` (every rig's
    samples ``(n_rigs, k, 5)``, its ``seq``, ``t`` [s] and valve drive ``u``), one per rig in rig
    order (``rigs``: of these rig indices only); rigs whose index is in ``with_u`` carry the drive [V]."""
    seq, t = int(blk.seq[j0]), blk.t[j0:j1].tolist()
    picked = blk.samples[:, j0:j1, :] if rigs is None else blk.samples[rigs, j0:j1, :]
    columns = picked.transpose(0, 2, 1).tolist()  # (rigs, 5, n)
    if not with_u:
        return [frame_payload(seq, t, c) for c in columns]
    index = range(len(columns)) if rigs is None else list(rigs)
    us = blk.u[index, j0:j1].tolist() if rigs is not None else blk.u[:, j0:j1].tolist()
    return [frame_payload(seq, t, c, us[k] if r in with_u else None) for k, (r, c) in enumerate(zip(index, columns))]
