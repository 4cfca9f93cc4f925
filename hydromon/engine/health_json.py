"""Health payloads of a batch of evaluations, as JSON bytes (``contract.Health``).

:func:`health_payload` is the definition: the dict the contract describes, through
``orjson.dumps``. :func:`health_payloads` gives the same bytes for a batch's arrays (a property
test holds them equal): one ``tolist`` per array, the finite masks and clipped confidences from
numpy for the whole batch, and per row dict displays rather than loops over the parameters.

JSON has no NaN or infinity: a parameter whose estimate or standard error is not finite is
left out; confidence is clipped to [0, 1] (0 when not finite, and never -0.0); ``level`` -1
is ``null`` with grade ``"unknown"``. ``ranges`` (the tag of the ranges the rig is graded on, null
when none) is always there; ``node`` and ``epoch`` when the monitor has them.
"""

from __future__ import annotations

import math

import numpy as np
import orjson

from hydromon.contract import GRADES, PARAM_NAMES

__all__ = ["health_payload", "health_payloads"]

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


def _display_12(r: list, k: tuple = PARAM_NAMES) -> dict:
    """``{PARAM_NAMES[i]: r[i]}`` for twelve names, as one dict display: 0.3 us, against 0.9 us
    for ``dict(zip(PARAM_NAMES, r))``, which builds a pair per entry."""
    return {k[0]: r[0], k[1]: r[1], k[2]: r[2], k[3]: r[3], k[4]: r[4], k[5]: r[5], k[6]: r[6], k[7]: r[7],
            k[8]: r[8], k[9]: r[9], k[10]: r[10], k[11]: r[11]}


def _zipped(r: list, k: tuple = PARAM_NAMES) -> dict:
    return dict(zip(k, r))


_by_name = _display_12 if len(PARAM_NAMES) == 12 else _zipped  # ``{PARAM_NAMES[i]: r[i]}``

_LEFT_OUT: dict[tuple, tuple] = {}  # finite mask -> the PARAM_NAMES it leaves out (at most 2 ** len(PARAM_NAMES))


def _finite_by_name(r: list, finite: list) -> dict:
    """``{name: r[i]}`` for the PARAM_NAMES whose ``finite`` entry is True, in PARAM_NAMES order:
    the full display less the names left out (deleting keys keeps the others' order)."""
    d = _by_name(r)
    mask = tuple(finite)
    out = _LEFT_OUT.get(mask)
    if out is None:
        out = _LEFT_OUT[mask] = tuple(k for k, m in zip(PARAM_NAMES, mask) if not m)
    for k in out:
        del d[k]
    return d


_GRADE_DICTS: dict[tuple, dict] = {}  # (graded, grades) -> param_grades (shared: only serialized)


def _grade_dict(graded: tuple, grades: tuple) -> dict:
    d = _GRADE_DICTS.get((graded, grades))
    if d is None:
        if len(_GRADE_DICTS) >= 100_000:  # bounded: 6 ** len(graded) per graded tuple
            _GRADE_DICTS.clear()
        d = _GRADE_DICTS[(graded, grades)] = {k: _GRADE_NAMES[g] for k, g in zip(graded, grades)}
    return d


def health_payloads(seqs: list, t: np.ndarray, level: np.ndarray, confidence: np.ndarray, params: np.ndarray,
                    std_errors: np.ndarray, grades: np.ndarray, statuses: list, graded, ranges=None,
                    node: str | None = None, epoch: int | None = None) -> list[bytes]:
    """Payloads of n evaluations: seqs (n ints), t [s] (n,), level (n,) in -1..4, confidence
    (n,), params and std_errors (n, len(PARAM_NAMES)) SI, grades (n, G >= len(graded)) in -1..4,
    statuses (n str), ``graded`` the graded names (one tuple for all, or one per evaluation),
    ``ranges`` the ranges' tag (one for all, or one per evaluation): :func:`health_payload` of
    each, byte for byte (a property test).

    Per row: the ``params`` / ``std_errors`` dicts from one display each (a row with all twelve
    finite, the common case, skips the mask), the ``param_grades`` dict from a cache by grades.
    """
    n = len(seqs)
    npar = len(PARAM_NAMES)
    each = graded if isinstance(graded, list) else [tuple(graded)] * n
    tags = ranges if isinstance(ranges, list) else [ranges] * n
    widest = max(map(len, each), default=0)
    if params.shape != (n, npar) or std_errors.shape != (n, npar) or grades.shape[0] != n or \
            (n and grades.shape[1] < widest) or len(each) != n or len(tags) != n:
        raise ValueError(f"shapes: params {params.shape}, std_errors {std_errors.shape}, grades {grades.shape} "
                         f"for {n} evaluations of {npar} parameters, {widest} graded")
    if n == 0:
        return []
    dumps, names, by_name, finite_by_name = orjson.dumps, _GRADE_NAMES, _by_name, _finite_by_name
    conf = np.asarray(confidence, dtype=np.float64)
    # min(1, max(0, c)) where finite, else 0; + 0.0 makes a -0.0 0.0 (max(0.0, -0.0) is 0.0)
    conf = (np.where(np.isfinite(conf), np.minimum(1.0, np.maximum(0.0, conf)), 0.0) + 0.0).tolist()
    p_fin, s_fin = np.isfinite(params), np.isfinite(std_errors)
    tail = {}
    if node is not None:
        tail["node"] = node
    if epoch is not None:
        tail["epoch"] = epoch
    return [dumps({
        "seq": seq, "t": tj,
        "grade": names[lv],
        "level": lv if lv >= 0 else None,
        "confidence": cj,
        "params": by_name(pj) if pa else finite_by_name(pj, pm),
        "param_grades": _grade_dict(gr, tuple(gj[:len(gr)])),
        "status": st,
        "std_errors": by_name(sj) if sa else finite_by_name(sj, sm),
        "ranges": tag,
        **tail,
    }) for seq, tj, lv, cj, pj, pa, pm, sj, sa, sm, gj, st, gr, tag in zip(
        seqs, t.tolist(), level.tolist(), conf, params.tolist(), p_fin.all(axis=1).tolist(), p_fin.tolist(),
        std_errors.tolist(), s_fin.all(axis=1).tolist(), s_fin.tolist(), grades.tolist(), statuses, each, tags)]
