"""The payloads of the bus: one pydantic model each, in SI units.

Every payload type is one model; its JSON Schema (``model_json_schema``) is what MCAP channels
carry and what docs/contract.md shows. Payloads are JSON.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from hydromon.contract.names import CHANNELS, GRADES, UNKNOWN
from hydromon.contract.rig import RigConfig

__all__ = ["Sample", "Health", "SAMPLE_COLUMNS", "SAMPLE_LIMITS", "SEQ_MAX", "RESTART_RUN", "STATUSES",
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


LEAF_MODELS = {"sample": Sample, "health": Health, "config": RigConfig, "event": Event}
"""The payload model of each leaf of a rig's keys."""


def schemas() -> dict[str, dict]:
    """JSON Schemas of every payload, by payload name."""
    return {m.__name__: m.model_json_schema(by_alias=True) for m in LEAF_MODELS.values()}
