"""Bus contract v1 (DESIGN.md section 3): key expressions and payload models.

Every payload type is one pydantic model; its JSON Schema (``model_json_schema``) is what
MCAP channels carry and what docs/contract.md shows. Payloads are JSON, SI units.
"""

from __future__ import annotations

import math
import re
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from monitor.names import GRADES, PARAM_NAMES  # the core's names, on the bus as they are
from plant_sim.params import RigConfig

__all__ = [
    "Sample", "Health", "RigConfig", "SAMPLE_COLUMNS", "GRADES", "STATUSES", "PARAM_NAMES", "SEQ_MAX", "RESTART_RUN", "SAMPLE_LIMITS",
    "RIG_ID_RE", "valid_rig_id", "sample_key", "health_key", "config_key", "liveliness_key",
    "parse_rig_key", "split_rig_key", "DEFAULT_NAMESPACE",
]

DEFAULT_NAMESPACE = "hydro"
SEQ_MAX = 2**63 - 1  # seq is a signed 64-bit count (the monitor keeps it in int64 arrays)
# Samples in a row below a rig's last seq, each above the one before, that the monitor takes as
# the rig's restart when it never saw the new run's seq 0 (lost while a peer reconnected)
RESTART_RUN = 50
# Magnitude limits of a sample's measured values (SI), far beyond any servo cylinder (strokes
# under 10 m, pressures under 10 kbar, spool strokes of millimetres, command voltages of
# volts) but below what overflows the estimators: one reading of 1e300 Pa used to leave a rig's
# estimates at -1e295 for good. A value outside is rejected as bad-value.
SAMPLE_LIMITS = {"ug": 1e3, "x1": 10.0, "x3": 1e9, "x4": 1e9, "x5": 0.1}
STATUSES = ("converging", "ok", "stale", "bad-input")
RIG_ID_RE = re.compile(r"[A-Za-z0-9_-]{1,64}")
_NS_RE = re.compile(r"[A-Za-z0-9_-]+(/[A-Za-z0-9_-]+)*")


def valid_rig_id(rig_id: str) -> bool:
    """True if ``rig_id`` is 1-64 chars of ``[A-Za-z0-9_-]`` (safe in keys and file names)."""
    return isinstance(rig_id, str) and RIG_ID_RE.fullmatch(rig_id) is not None


def _check_ns(ns: str) -> str:
    if not _NS_RE.fullmatch(ns):
        raise ValueError(f"namespace {ns!r} must be /-separated chunks of [A-Za-z0-9_-]")
    return ns


def _rig_key(ns: str, rig_id: str, leaf: str) -> str:
    if not valid_rig_id(rig_id):
        raise ValueError(f"rig id {rig_id!r} must be 1-64 chars of [A-Za-z0-9_-]")
    return f"{_check_ns(ns)}/rig/{rig_id}/{leaf}"


def sample_key(rig_id: str, ns: str = DEFAULT_NAMESPACE) -> str:
    return _rig_key(ns, rig_id, "sample")


def health_key(rig_id: str, ns: str = DEFAULT_NAMESPACE) -> str:
    return _rig_key(ns, rig_id, "health")


def config_key(rig_id: str, ns: str = DEFAULT_NAMESPACE) -> str:
    return _rig_key(ns, rig_id, "config")


def liveliness_key(node: str, ns: str = DEFAULT_NAMESPACE) -> str:
    if not valid_rig_id(node):
        raise ValueError(f"node name {node!r} must be 1-64 chars of [A-Za-z0-9_-]")
    return f"{_check_ns(ns)}/monitor/{node}"


def split_rig_key(key: str, ns: str = DEFAULT_NAMESPACE) -> tuple[str, str] | str:
    """``(rig_id, leaf)`` for a key ``<ns>/rig/<id>/<leaf>`` of the contract, else why not: a
    message for the rejection log, starting with ``bad-key:`` (not a rig key of ``ns``) or
    ``bad-rig-id:`` (the layout, but an id outside the contract's)."""
    prefix = f"{ns}/rig/"
    if not key.startswith(prefix):
        return f"bad-key: not under {prefix}"
    parts = key[len(prefix):].split("/")
    if len(parts) != 2 or parts[1] not in ("sample", "health", "config"):
        return "bad-key: expected <ns>/rig/<id>/sample, config or health"
    if not valid_rig_id(parts[0]):
        return f"bad-rig-id: {parts[0][:80]!r} is not 1-64 chars of [A-Za-z0-9_-]"
    return parts[0], parts[1]


def parse_rig_key(key: str, ns: str = DEFAULT_NAMESPACE) -> tuple[str, str] | None:
    """``(rig_id, leaf)`` for a key ``<ns>/rig/<id>/<leaf>`` of the contract, else None."""
    parts = split_rig_key(key, ns)
    return None if isinstance(parts, str) else parts


class _Payload(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class Sample(_Payload):
    """One sample of a rig, ``<ns>/rig/<id>/sample``.

    seq counts samples per rig from 0 (at most 2**63 - 1); t is the rig clock [s]; ug [V]; x1 piston position [m];
    x3, x4 chamber pressures [Pa]; x5 spool position [m]. Magnitudes are bounded (SAMPLE_LIMITS:
    |ug| <= 1e3 V, |x1| <= 10 m, |x3|, |x4| <= 1e9 Pa, |x5| <= 0.1 m).
    """

    seq: int = Field(ge=0, le=SEQ_MAX)
    t: float
    ug: float = Field(ge=-SAMPLE_LIMITS["ug"], le=SAMPLE_LIMITS["ug"])
    x1: float = Field(ge=-SAMPLE_LIMITS["x1"], le=SAMPLE_LIMITS["x1"])
    x3: float = Field(ge=-SAMPLE_LIMITS["x3"], le=SAMPLE_LIMITS["x3"])
    x4: float = Field(ge=-SAMPLE_LIMITS["x4"], le=SAMPLE_LIMITS["x4"])
    x5: float = Field(ge=-SAMPLE_LIMITS["x5"], le=SAMPLE_LIMITS["x5"])

    @field_validator("t", "ug", "x1", "x3", "x4", "x5", mode="before")
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
SAMPLE_COLUMNS = tuple(name for name in Sample.model_fields if name != "seq")


class Health(_Payload):
    """The monitor's verdict on a rig, ``<ns>/rig/<id>/health``.

    params are by the names in PARAM_NAMES (SI); param_grades grade the graded ones;
    level is 0 (health) .. 4 (fault), null while the grade is unknown.
    """

    seq: int = Field(ge=0, le=SEQ_MAX)
    t: float
    grade: Literal[GRADES + ("unknown",)]
    level: int | None = Field(None, ge=0, le=4)
    confidence: float = Field(ge=0.0, le=1.0)
    params: dict[str, float]
    param_grades: dict[str, Literal[GRADES + ("unknown",)]]
    status: Literal[STATUSES]
    std_errors: dict[str, float] = Field(default_factory=dict)


def schemas() -> dict[str, dict]:
    """JSON Schemas of every payload, by payload name."""
    return {m.__name__: m.model_json_schema() for m in (Sample, Health, RigConfig)}
