"""Validation at the edge: raw bus payloads into contract values, or a counted reason.

The monitor never crashes on input and never feeds an estimator a bad value: a message is
rejected, and counted under a reason, when

==================  ======================================================================
``bad-key``         the key is not ``<ns>/rig/<chunk>/sample`` or ``.../config``
``bad-rig-id``      the rig chunk is not 1-64 chars of ``[A-Za-z0-9_-]``
``not-json``        the payload does not parse as JSON
``non-finite``      NaN or +-inf, as a JSON token (``NaN``, ``Infinity``, ``1e400``) or as
                    a string spelling one (``"nan"``, ``"inf"``)
``missing-field``   a field of the contract model is absent
``wrong-type``      not a JSON object, or a field of the wrong type (a string, a bool, a
                    float seq)
``unknown-field``   a field the contract does not have (models forbid extras)
``bad-value``       a value out of its range (seq < 0, a non-positive area), a config
                    whose sample rate the monitor does not run at, or a frame whose arrays
                    differ in length, are empty or longer than FRAME_MAX, or whose times do
                    not strictly increase
``too-many-rigs``   a new rig id beyond the monitor's limit of rigs (``--max-rigs``)
``too-large``       a bus payload of more than ``PAYLOAD_MAX`` bytes (a frame of FRAME_MAX
                    samples written out in full takes about 200 kB): the monitor node counts
                    it unread (``MonitorCore.refuse_unread``)
==================  ======================================================================
"""

from __future__ import annotations

import json
import math
from operator import itemgetter

import numpy as np
import orjson
from pydantic import ValidationError

from hydromon.contract import SAMPLE_COLUMNS, SAMPLE_LIMITS, SEQ_MAX, Frame, RigConfig, Sample

__all__ = ["PAYLOAD_MAX", "REJECT_REASONS", "VALUE_LIMITS", "Rejected", "decode_json", "too_large_words",
           "parse_config", "parse_sample", "parse_frame"]

REJECT_REASONS = ("bad-key", "bad-rig-id", "not-json", "non-finite", "missing-field", "wrong-type",
                  "unknown-field", "bad-value", "too-many-rigs", "too-large")
PAYLOAD_MAX = 1 << 20
"""The largest bus payload [B] the monitor node reads; a larger one is refused unread
(``too-large``): copying and parsing megabytes of garbage would hold up every rig's health."""
_SAMPLE_FIELD_SET = frozenset(("seq", *SAMPLE_COLUMNS))  # a sample without the optional drive u
_NUM = (float, int)
_SEQ = itemgetter(0)
_L_UG, _L_X1, _L_X3, _L_X4, _L_X5 = (SAMPLE_LIMITS[k] for k in SAMPLE_COLUMNS[1:])
#: |value| limits of the columns (ug, x1, x3, x4, x5), for checking a whole batch at once
VALUE_LIMITS = np.array([_L_UG, _L_X1, _L_X3, _L_X4, _L_X5])


def _in_limits(ug, x1, x3, x4, x5) -> bool:
    return abs(ug) <= _L_UG and abs(x1) <= _L_X1 and abs(x3) <= _L_X3 and abs(x4) <= _L_X4 and abs(x5) <= _L_X5


class Rejected(ValueError):
    """A message failed validation at the edge; ``reason`` is one of REJECT_REASONS."""

    def __init__(self, reason: str, detail: str):
        super().__init__(f"{reason}: {detail}")
        self.reason, self.detail = reason, detail


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
        elif typ == "extra_forbidden":  # whatever its value ("INF" in an unknown field is not a non-finite reading)
            kinds.append(("unknown-field", loc))
        elif typ == "finite_number" or "finite" in e.get("msg", "") or _nonfinite_string(value):
            kinds.append(("non-finite", loc))
        elif typ in ("greater_than", "greater_than_equal", "less_than", "less_than_equal", "too_short", "too_long",
                     "frame_shape"):
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
        raise Rejected("non-finite", "NaN, infinity or a number beyond a float's range in the JSON") from None


def too_large_words(size: int) -> str:
    """Why a payload of ``size`` bytes is refused unread."""
    return f"{size} bytes; the monitor reads payloads of at most {PAYLOAD_MAX} bytes"


def parse_sample(obj) -> tuple:
    """``(seq, t, ug, x1, x3, x4, x5)`` of a decoded sample payload, validated as
    ``contract.Sample`` (a fast path for the common valid case; the model decides the rest),
    and the valve drive ``u`` [V] as an eighth value when the sample carries one."""
    if type(obj) is dict and len(obj) == 7 and obj.keys() == _SAMPLE_FIELD_SET:
        seq = obj["seq"]
        t, ug, x1, x3, x4, x5 = obj["t"], obj["ug"], obj["x1"], obj["x3"], obj["x4"], obj["x5"]
        # the common case, what our sim sends: an int seq and six floats (no conversions)
        if type(seq) is int and 0 <= seq <= SEQ_MAX and type(t) is float and type(ug) is float and type(x1) is float \
                and type(x3) is float and type(x4) is float and type(x5) is float \
                and math.isfinite(t + ug + x1 + x3 + x4 + x5) and _in_limits(ug, x1, x3, x4, x5):
            return (seq, t, ug, x1, x3, x4, x5)
        if type(seq) is int and 0 <= seq <= SEQ_MAX:
            try:
                # finite floats (orjson gives no NaN/inf) or ints; bools, str, None fail here
                if type(t) in _NUM and type(ug) in _NUM and type(x1) in _NUM and type(x3) in _NUM and \
                        type(x4) in _NUM and type(x5) in _NUM and math.isfinite(t + ug + x1 + x3 + x4 + x5) \
                        and _in_limits(ug, x1, x3, x4, x5):
                    return (seq, float(t), float(ug), float(x1), float(x3), float(x4), float(x5))
            except OverflowError:  # huge ints
                pass
    if not isinstance(obj, dict):
        raise Rejected("wrong-type", f"payload is a JSON {type(obj).__name__}, not an object")
    try:
        s = Sample.model_validate(obj)
    except ValidationError as exc:
        raise Rejected(*_classify(exc, obj)) from None
    except OverflowError:  # an integer beyond any double (the bus's JSON decode refuses it first)
        raise Rejected("non-finite", "a number beyond the range of a double") from None
    if s.u is not None:
        return (s.seq, s.t, s.ug, s.x1, s.x3, s.x4, s.x5, s.u)
    return (s.seq, s.t, s.ug, s.x1, s.x3, s.x4, s.x5)  # pragma: no cover (fast path takes these)


def parse_frame(obj) -> Frame:
    """A decoded frame payload validated as ``contract.Frame`` (the reasons as a sample's; a frame's
    shape, its arrays' lengths and its times, is ``bad-value``). ``hydromon.engine.frames`` takes
    the common valid case faster, into arrays, and leaves every other payload to this."""
    if not isinstance(obj, dict):
        raise Rejected("wrong-type", f"payload is a JSON {type(obj).__name__}, not an object")
    try:
        return Frame.model_validate(obj)
    except ValidationError as exc:
        raise Rejected(*_classify(exc, obj)) from None
    except OverflowError:
        raise Rejected("non-finite", "a number beyond the range of a double") from None



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
