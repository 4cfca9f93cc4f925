"""Health payloads of a batch of evaluations, as JSON bytes (``contract.Health``).

:func:`health_payload` is the definition: the dict the contract describes, through
``orjson.dumps``. :func:`health_payloads` gives the same bytes for a batch's arrays (a property
test holds them equal) without a Python dict per payload: orjson writes all the batch's floats
at once (one numpy array: the same shortest round-trip digits as for a float in a dict, ``null``
for a non-finite one), and a compiled loop (:func:`_write`) lays each payload out around them
from byte pieces: keys, grade names, and the JSON of each distinct status, graded tuple, ranges
tag and node/epoch tail: 1.3-1.6 us a payload, against 4-9 us through a dict per payload
(the two on the same batch of 250 evaluations, one process).

JSON has no NaN or infinity: a parameter whose estimate or standard error is not finite is
left out; confidence is clipped to [0, 1] (0 when not finite, and never -0.0); ``level`` -1
is ``null`` with grade ``"unknown"``. ``ranges`` (the tag of the ranges the rig is graded on, null
when none) is always there; ``node`` and ``epoch`` when the monitor has them.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import orjson

from hydromon.contract import GRADES, PARAM_NAMES

__all__ = ["HealthWriter", "health_payload", "health_payloads"]

_GRADE_NAMES = GRADES + ("unknown",)  # level -1 -> "unknown"


def health_payload(seq: int, t: float, level: int, confidence: float, params, std_errors, grades,
                   status: str, graded: tuple, ranges: str | None = None, node: str | None = None,
                   epoch: int | None = None) -> bytes:
    """One health payload, the defining way (params/std_errors by PARAM_NAMES, grades by graded)."""
    conf = min(1.0, max(0.0, confidence)) if math.isfinite(confidence) else 0.0
    d = {
        "seq": seq, "t": t,
        "grade": _GRADE_NAMES[level],
        "level": level if level >= 0 else None,
        "confidence": conf,
        "params": {k: v for k, v in zip(PARAM_NAMES, params) if math.isfinite(v)},
        "param_grades": {k: _GRADE_NAMES[g] for k, g in zip(graded, grades)},
        "status": status,
        "std_errors": {k: v for k, v in zip(PARAM_NAMES, std_errors) if math.isfinite(v)},
        "ranges": ranges,
    }
    if node is not None:
        d["node"] = node
    if epoch is not None:
        d["epoch"] = epoch
    return orjson.dumps(d)



_Q = orjson.dumps  # JSON text of a key or string, escaped as orjson escapes it in the dict


class _Pieces:
    """Byte pieces the writer copies, interned: ``index(key)`` is the number of the piece ``key``
    (bytes: as they are; a str or None: its JSON), ``arrays()`` all of them as one uint8 array with
    start and end offsets. Bounded: :meth:`trim`, between batches, starts over past ``limit``
    pieces (a fleet's distinct statuses and tags are far fewer); numbers given out stay valid
    until then."""

    def __init__(self, fixed: list[bytes], limit: int = 100_000):
        self._fixed, self.limit = list(fixed), limit
        self._reset()

    def _reset(self) -> None:
        self._ids: dict = {}
        self._list: list[bytes] = []
        self._made = None
        for b in self._fixed:
            self.index(b)

    def trim(self) -> None:
        if len(self._list) > self.limit:
            self._reset()

    def index(self, key: bytes | str | None) -> int:
        i = self._ids.get(key)
        if i is None:
            i = self._ids[key] = len(self._list)
            self._list.append(key if isinstance(key, bytes) else _Q(key))
            self._made = None
        return i

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self._made is None:
            lens = np.fromiter(map(len, self._list), np.int64, len(self._list))
            ends = np.cumsum(lens)
            self._made = (np.frombuffer(b"".join(self._list), np.uint8), ends - lens, ends)
        return self._made


_P = len(PARAM_NAMES)
# fixed pieces: 0.._P-1 the params' keys '"name":', then the grade names' strings, the levels
_KEYS = [_Q(k) + b":" for k in PARAM_NAMES]
_GRADE_STR = [_Q(g) for g in _GRADE_NAMES]  # index level (-1: the last, "unknown")
_LEVEL_TXT = [b"0", b"1", b"2", b"3", b"4", b"null"]
_FIXED = _KEYS + _GRADE_STR + _LEVEL_TXT
_G0, _L0 = _P, _P + len(_GRADE_STR)  # first grade-name piece, first level piece

_SEQ, _T, _GRADE, _LEVEL, _CONF = b'{"seq":', b',"t":', b',"grade":', b',"level":', b',"confidence":'
_PARAMS, _PGRADES, _STATUS, _STD, _RANGES = b',"params":{', b'},"param_grades":{', b'},"status":', \
    b',"std_errors":{', b'},"ranges":'
_TEMPLATE = [_SEQ, _T, _GRADE, _LEVEL, _CONF, _PARAMS, _PGRADES, _STATUS, _STD, _RANGES, b"}"]
_TEMPLATE_BYTES = np.frombuffer(b"".join(_TEMPLATE), np.uint8)
_TEMPLATE_ENDS = np.cumsum([len(b) for b in _TEMPLATE])


@numba.njit(cache=True, nogil=True, inline="always")
def _copy(out, o, src, a, b):
    e = o + b - a
    out[o:e] = src[a:b]
    return e


@numba.njit(cache=True, nogil=True)
def _write(text, seqs, levels, graded, grades, row_pieces, tail, pieces, p0, p1, tpl, tpl_end, out, ends):
    """Each payload j into ``out`` (ending at ``ends[j]``): ``text`` the JSON array of the batch's
    floats, 26 a row (t, confidence, the params, the std errors); ``graded`` (n, P) the graded
    parameters' indices (-1 after the last); ``row_pieces`` (n, 2) the status and ranges pieces;
    ``tail`` the node/epoch piece or -1."""
    n, npar = levels.shape[0], _P
    c = 1  # cursor in text, past "["
    o = 0
    digits = np.empty(20, np.uint8)
    for j in range(n):
        o = _copy(out, o, tpl, 0, tpl_end[0])
        s = seqs[j]
        m = 0
        while True:
            digits[m] = 48 + s % 10
            s //= 10
            m += 1
            if s == 0:
                break
        for i in range(m - 1, -1, -1):
            out[o] = digits[i]
            o += 1
        for f in range(2 + 2 * npar):
            e = c
            while text[e] != 44 and text[e] != 93:  # "," or "]"
                e += 1
            if f == 0:
                o = _copy(out, o, tpl, tpl_end[0], tpl_end[1])
                o = _copy(out, o, text, c, e)
                lv = levels[j]
                g = _G0 + (lv if lv >= 0 else 5)
                o = _copy(out, o, tpl, tpl_end[1], tpl_end[2])
                o = _copy(out, o, pieces, p0[g], p1[g])
                o = _copy(out, o, tpl, tpl_end[2], tpl_end[3])
                g = _L0 + (lv if lv >= 0 else 5)
                o = _copy(out, o, pieces, p0[g], p1[g])
                o = _copy(out, o, tpl, tpl_end[3], tpl_end[4])
            elif f == 1:
                o = _copy(out, o, text, c, e)
                o = _copy(out, o, tpl, tpl_end[4], tpl_end[5])
                first = True
            else:
                if f == 2 + npar:  # params done: the grades, the status, the std errors
                    o = _copy(out, o, tpl, tpl_end[5], tpl_end[6])
                    for q in range(npar):
                        gi = graded[j, q]
                        if gi < 0:
                            break
                        if q > 0:
                            out[o] = 44
                            o += 1
                        o = _copy(out, o, pieces, p0[gi], p1[gi])
                        gv = grades[j, q]
                        g = _G0 + (gv if gv >= 0 else 5)
                        o = _copy(out, o, pieces, p0[g], p1[g])
                    o = _copy(out, o, tpl, tpl_end[6], tpl_end[7])
                    o = _copy(out, o, pieces, p0[row_pieces[j, 0]], p1[row_pieces[j, 0]])
                    o = _copy(out, o, tpl, tpl_end[7], tpl_end[8])
                    first = True
                if text[c] != 110:  # not "null": a finite number, kept
                    if not first:
                        out[o] = 44
                        o += 1
                    first = False
                    key = (f - 2) % npar
                    o = _copy(out, o, pieces, p0[key], p1[key])
                    o = _copy(out, o, text, c, e)
            c = e + 1
        o = _copy(out, o, tpl, tpl_end[8], tpl_end[9])
        o = _copy(out, o, pieces, p0[row_pieces[j, 1]], p1[row_pieces[j, 1]])
        if tail >= 0:
            o = _copy(out, o, pieces, p0[tail], p1[tail])
        o = _copy(out, o, tpl, tpl_end[9], tpl_end[10])
        ends[j] = o
    return o


class HealthWriter:
    """:func:`health_payloads` with its interned pieces kept between batches (a monitor core holds
    one; the pieces of a fleet's statuses, graded tuples and tags are made once)."""

    def __init__(self):
        self.pieces = _Pieces(_FIXED)
        self._graded: dict[tuple, np.ndarray] = {}

    def _graded_row(self, graded: tuple) -> np.ndarray:
        """The pieces '"name":' of a graded tuple's names, -1 after the last ((P,) int64)."""
        row = self._graded.get(graded)
        if row is None:
            if len(self._graded) >= 10_000:
                self._graded.clear()
            row = np.full(_P, -1, np.int64)
            row[:len(graded)] = [PARAM_NAMES.index(k) for k in graded]
            self._graded[graded] = row
        return row

    def payloads(self, seqs: list, t: np.ndarray, level: np.ndarray, confidence: np.ndarray, params: np.ndarray,
                 std_errors: np.ndarray, grades: np.ndarray, statuses: list, graded, ranges=None,
                 node: str | None = None, epoch: int | None = None) -> list[bytes]:
        """See :func:`health_payloads`."""
        n = len(seqs)
        each = graded if isinstance(graded, list) else [tuple(graded)] * n
        tags = ranges if isinstance(ranges, list) else [ranges] * n
        widest = max(map(len, each), default=0)
        if params.shape != (n, _P) or std_errors.shape != (n, _P) or grades.shape[0] != n or \
                (n and grades.shape[1] < widest) or len(each) != n or len(tags) != n or len(statuses) != n:
            raise ValueError(f"shapes: params {params.shape}, std_errors {std_errors.shape}, grades {grades.shape} "
                             f"for {n} evaluations of {_P} parameters, {widest} graded")
        if n == 0:
            return []
        seq_a, lv_a = np.asarray(seqs, dtype=np.int64), np.asarray(level, dtype=np.int64)
        # the writer indexes its pieces by these without bounds checks: refuse what the contract never holds
        if seq_a.min() < 0 or lv_a.min() < -1 or lv_a.max() > 4 or (widest and (
                grades[:, :widest].min() < -1 or grades[:, :widest].max() > 4)):
            raise ValueError("seqs must be >= 0, levels and grades in -1..4")
        conf = np.asarray(confidence, dtype=np.float64)
        # min(1, max(0, c)) where finite, else 0; + 0.0 makes a -0.0 0.0 (max(0.0, -0.0) is 0.0)
        conf = np.where(np.isfinite(conf), np.minimum(1.0, np.maximum(0.0, conf)), 0.0) + 0.0
        nums = np.empty((n, 2 + 2 * _P))
        nums[:, 0], nums[:, 1], nums[:, 2:2 + _P], nums[:, 2 + _P:] = t, conf, params, std_errors
        text = np.frombuffer(orjson.dumps(nums.reshape(-1), option=orjson.OPT_SERIALIZE_NUMPY), np.uint8)
        pieces = self.pieces
        pieces.trim()
        index = pieces.index
        row_pieces = np.array([(index(st), index(tag)) for st, tag in zip(statuses, tags)],
                              dtype=np.int64).reshape(n, 2)
        tail_b = (b',"node":' + _Q(node) if node is not None else b"") + \
            (b',"epoch":' + str(int(epoch)).encode() if epoch is not None else b"")
        tail = index(tail_b) if tail_b else -1
        g_rows = np.array([self._graded_row(g) for g in each])
        g_vals = np.full((n, _P), -1, np.int64)
        g_vals[:, :widest] = grades[:, :widest]
        p_all, p0, p1 = pieces.arrays()
        # a row's bytes at most: the template, 19 digits of seq, its numbers (in len(text)), the
        # twice twelve keys, and per graded name a key, a grade and a comma, plus four more pieces
        bound = len(text) + n * (len(_TEMPLATE_BYTES) + 20 + 2 * sum(map(len, _KEYS)) + len(tail_b)
                                 + (2 * _P + 4) * int((p1 - p0).max()) + _P)
        out = np.empty(bound, np.uint8)
        ends = np.empty(n, np.int64)
        _write(text, seq_a, lv_a, g_rows, g_vals, row_pieces,
               tail, p_all, p0, p1, _TEMPLATE_BYTES, _TEMPLATE_ENDS, out, ends)
        data = out.tobytes()  # one copy; the payloads are slices of it
        starts = [0, *ends[:-1].tolist()]
        return [data[a:b] for a, b in zip(starts, ends.tolist())]


def health_payloads(seqs: list, t: np.ndarray, level: np.ndarray, confidence: np.ndarray, params: np.ndarray,
                    std_errors: np.ndarray, grades: np.ndarray, statuses: list, graded, ranges=None,
                    node: str | None = None, epoch: int | None = None) -> list[bytes]:
    """Payloads of n evaluations: seqs (n ints >= 0), t [s] (n,), level (n,) in -1..4, confidence
    (n,), params and std_errors (n, len(PARAM_NAMES)) SI, grades (n, G >= len(graded)) in -1..4,
    statuses (n str), ``graded`` the graded names (one tuple for all, or one per evaluation),
    ``ranges`` the ranges' tag (one for all, or one per evaluation): :func:`health_payload` of
    each, byte for byte (a property test). A loop that writes batch after batch keeps a
    :class:`HealthWriter` (this makes one a call)."""
    return HealthWriter().payloads(seqs, t, level, confidence, params, std_errors, grades, statuses, graded,
                                   ranges, node, epoch)
