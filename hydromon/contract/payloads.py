"""The payloads of the bus: one pydantic model each, in SI units.

Every payload type is one model; its JSON Schema (``model_json_schema``) is what MCAP channels
carry and what docs/contract.md shows. Payloads are JSON.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from hydromon.contract.names import CHANNELS, GRADES, UNKNOWN
from hydromon.contract.rig import RigConfig

__all__ = ["Sample", "Frame", "FRAME_MAX", "Health", "SAMPLE_COLUMNS", "SAMPLE_LIMITS", "SEQ_MAX", "RESTART_RUN", "STATUSES",
           "LEAF_MODELS", "DRIVE", "DRIVE_LIMIT", "EVENT_KINDS", "Event", "schemas"]

SEQ_MAX = 2**63 - 1  # seq is a signed 64-bit count (the monitor keeps it in int64 arrays)
# Samples in a row below a rig's last seq, each above the one before, that the monitor takes as
# the rig's restart when it never saw the new run's seq 0 (lost while a peer reconnected)
RESTART_RUN = 50
# Magnitude limits of a sample's measured values (SI), far beyond any servo cylinder (strokes
# under 10 m, pressures under 10 kbar, spool strokes of millimetres, command voltages of
# volts) but below what overflows the estimators (one reading of 1e300 Pa would leave a rig's
# estimates at -1e295 for good). A value outside is rejected as bad-value.
SAMPLE_LIMITS = {"ug": 1e3, "x1": 10.0, "x3": 1e9, "x4": 1e9, "x5": 0.1}
DRIVE_LIMIT = 1e3  # [V] |u|, the optional valve drive: the command's limit
STATUSES = ("converging", "ok", "stale", "bad-input", "uncalibrated", "commissioning")


class _Payload(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class Sample(_Payload):
    """One sample of a rig, ``<ns>/rig/<id>/sample``.

    seq counts samples per rig from 0 (at most 2**63 - 1); t is the rig clock [s]; ug [V]; x1 piston position [m];
    x3, x4 chamber pressures [Pa]; x5 spool position [m]. Magnitudes are bounded (SAMPLE_LIMITS:
    |ug| <= 1e3 V, |x1| <= 10 m, |x3|, |x4| <= 1e9 Pa, |x5| <= 0.1 m).

    u [V], optional: the valve drive signal the rig's controller sends to the valve amplifier
    (|u| <= 1e3 V). When present the monitor takes it as the valve's input; without it, it
    assumes the rig constants' proportional loop ``u = K_p (ug - K_f x1)``.
    """

    seq: int = Field(ge=0, le=SEQ_MAX)
    t: float
    ug: float = Field(ge=-SAMPLE_LIMITS["ug"], le=SAMPLE_LIMITS["ug"])
    x1: float = Field(ge=-SAMPLE_LIMITS["x1"], le=SAMPLE_LIMITS["x1"])
    x3: float = Field(ge=-SAMPLE_LIMITS["x3"], le=SAMPLE_LIMITS["x3"])
    x4: float = Field(ge=-SAMPLE_LIMITS["x4"], le=SAMPLE_LIMITS["x4"])
    x5: float = Field(ge=-SAMPLE_LIMITS["x5"], le=SAMPLE_LIMITS["x5"])
    u: float | None = Field(None, ge=-DRIVE_LIMIT, le=DRIVE_LIMIT)

    @field_validator("u", mode="before")
    @classmethod
    def _optional_number(cls, v):
        return v if v is None else cls._number(v)

    @field_validator("t", *CHANNELS, mode="before")
    @classmethod
    def _number(cls, v):
        # JSON booleans are not numbers here, and neither are strings
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError("must be a number")
        if not math.isfinite(v):
            raise ValueError("must be finite")
        return v

    @field_validator("seq", mode="before")
    @classmethod
    def _int(cls, v):
        if isinstance(v, bool) or not isinstance(v, int):
            raise ValueError("must be an integer")
        return v


# the measured columns of a sample, in payload order: t [s], ug [V], x1 [m], x3 [Pa], x4 [Pa], x5 [m]
# (a CSV record's header and the columns of an MCAP's sample array)
SAMPLE_COLUMNS = tuple(name for name in Sample.model_fields if name not in ("seq", "u"))
DRIVE = "u"
"""The optional field of a sample: the valve drive [V]."""


FRAME_MAX = 1000
"""Most samples in one frame (10 s at 100 Hz): bounds the work of one message."""


def _channel(what: str, limit: float):
    """A frame's column: 1..FRAME_MAX numbers, each within ``limit`` as in a sample."""
    return Annotated[list[Annotated[float, Field(ge=-limit, le=limit)]],
                     Field(min_length=1, max_length=FRAME_MAX, description=f"{what} of each sample")]


class Frame(_Payload):
    """N consecutive samples of one rig in one message, ``<ns>/rig/<id>/frame`` (1 <= N <= FRAME_MAX).

    seq is the first sample's seq: the samples are seq, seq + 1, ..., seq + N - 1 (so a frame
    has no gap inside; the last one at most 2**63 - 1). t [s] are the sample times on the rig
    clock, strictly increasing; ug [V], x1 [m], x3, x4 [Pa], x5 [m] (and the optional valve drive
    u [V]) one number per sample, each array of the same length N, each value finite and within
    the limits of a :class:`Sample`'s. Sample i of the frame is the Sample ``{seq: seq + i,
    t: t[i], ug: ug[i], ...}``: a monitor grades a rig the same whether it sends samples or frames.
    """

    seq: int = Field(ge=0, le=SEQ_MAX)
    t: Annotated[list[float], Field(min_length=1, max_length=FRAME_MAX,
                                    description="rig clock time [s] of each sample, strictly increasing")]
    ug: _channel("command ug [V]", SAMPLE_LIMITS["ug"])
    x1: _channel("piston position x1 [m]", SAMPLE_LIMITS["x1"])
    x3: _channel("chamber pressure x3 [Pa]", SAMPLE_LIMITS["x3"])
    x4: _channel("chamber pressure x4 [Pa]", SAMPLE_LIMITS["x4"])
    x5: _channel("spool position x5 [m]", SAMPLE_LIMITS["x5"])
    u: _channel("valve drive u [V]", DRIVE_LIMIT) | None = None

    @field_validator("u", mode="before")
    @classmethod
    def _optional_numbers(cls, v):
        return v if v is None else cls._numbers(v)

    @field_validator("t", *CHANNELS, mode="before")
    @classmethod
    def _numbers(cls, v):
        # each element as a sample's field (no bools, no strings, finite)
        if not isinstance(v, list):
            raise ValueError("must be an array of numbers")
        for x in v:
            Sample._number(x)
        return v

    _seq_int = field_validator("seq", mode="before")(Sample._int.__func__)

    @model_validator(mode="after")
    def _shape(self):
        n = len(self.t)
        for name in (*CHANNELS, "u"):
            col = getattr(self, name)
            if col is not None and len(col) != n:
                raise PydanticCustomError("frame_shape", "{name} has {got} values for {n} sample times",
                                          {"name": name, "got": len(col), "n": n})
        if self.seq + n - 1 > SEQ_MAX:
            raise PydanticCustomError("frame_shape", "the last sample's seq is beyond 2**63 - 1")
        if any(b <= a for a, b in zip(self.t, self.t[1:])):
            raise PydanticCustomError("frame_shape", "t must be strictly increasing")
        return self


class Health(_Payload):
    """The monitor's verdict on a rig, ``<ns>/rig/<id>/health``.

    params are by the names in PARAM_NAMES (SI); param_grades grade the graded ones;
    level is 0 (health) .. 4 (fault), null while the grade is unknown. ranges names the health
    ranges the rig is graded on (absent or null: none apply, the rig is not graded). node and
    epoch say who said it: the monitor node's name and its start (a count that grows with every
    start of that node), so a reader can tell the rig's current monitor from an old or a forged one.
    """

    seq: int = Field(ge=0, le=SEQ_MAX)
    t: float
    grade: Literal[GRADES + (UNKNOWN,)]
    level: int | None = Field(None, ge=0, le=4)
    confidence: float = Field(ge=0.0, le=1.0)
    params: dict[str, float]
    param_grades: dict[str, Literal[GRADES + (UNKNOWN,)]]
    status: Literal[STATUSES]
    std_errors: dict[str, float] = Field(default_factory=dict)
    ranges: str | None = Field(None, max_length=120)
    node: str | None = Field(None, pattern=r"^[A-Za-z0-9_-]{1,64}$")
    epoch: int | None = Field(None, ge=0, le=SEQ_MAX)


EVENT_KINDS = ("grade", "status")


class Event(_Payload):
    """A change of a rig's verdict, ``<ns>/rig/<id>/event``: its grade or its status moved (after
    the grading's hysteresis, so a flapping estimate makes no event).

    seq and t are those of the sample after which the change was seen [s]; ``from``/``to`` the
    grades (``kind`` grade) or statuses (``kind`` status) before and after; reason says why in
    words; node and epoch name the monitor that saw it, as in health.
    """

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, populate_by_name=True)
    seq: int = Field(ge=0, le=SEQ_MAX)
    t: float
    kind: Literal[EVENT_KINDS]
    from_: str = Field(alias="from", max_length=32)
    to: str = Field(max_length=32)
    reason: str = Field("", max_length=400)
    node: str | None = Field(None, pattern=r"^[A-Za-z0-9_-]{1,64}$")
    epoch: int | None = Field(None, ge=0, le=SEQ_MAX)


LEAF_MODELS = {"sample": Sample, "frame": Frame, "health": Health, "config": RigConfig, "event": Event}
"""The payload model of each leaf of a rig's keys."""


def schemas() -> dict[str, dict]:
    """JSON Schemas of every payload, by payload name."""
    return {m.__name__: m.model_json_schema(by_alias=True) for m in LEAF_MODELS.values()}
