"""The exit status of the commands that give a verdict (``evaluate``, ``audit``, ``watch --once``):
one rule, so that ``hydromon CMD ... && next-step`` means the same everywhere. (``replay --direct``
prints the verdict sequence itself, each with its status, and exits 0 once it has replayed.)

| status | meaning |
| --- | --- |
| 0 | every rig graded, and the grade can be trusted (status ``ok``) |
| 1 | a rig graded but not to be trusted, or not graded: status ``bad-input``, ``uncalibrated``, ``stale``, ``converging`` or ``commissioning``; ``audit``: the record does not obey the model |
| 2 | a usage error: a bad option, or a file that cannot be read as what it should be (``hydromon.cli.main``) |
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["GRADED", "NOT_TRUSTED", "USAGE", "TRUSTED_STATUS", "exit_status"]

GRADED, NOT_TRUSTED, USAGE = 0, 1, 2
TRUSTED_STATUS = "ok"


def exit_status(statuses: Iterable[str]) -> int:
    """0 when there is a status and every one is ``ok``, else 1."""
    statuses = list(statuses)
    return GRADED if statuses and all(s == TRUSTED_STATUS for s in statuses) else NOT_TRUSTED
