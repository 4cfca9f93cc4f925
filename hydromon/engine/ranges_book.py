"""Which health ranges grade which rig, and why a rig has none.

A rig is graded only on ranges made for its constants (``monitor.ranges.Ranges.made_for``): its
own ranges when it has some (a commissioned file in the monitor's ``--ranges-dir``, or the one
``--ranges FILE`` names), else the default ranges when they were made for its constants (the
shipped ones are the reference rig's), else none: the rig is ``uncalibrated``, its parameters
reported, its grade unknown, and the reason says how to commission it.
"""

from __future__ import annotations

from dataclasses import dataclass

from hydromon.contract import RigConfig
from monitor.ranges import Ranges

__all__ = ["RigRanges", "RangesBook", "COMMISSION_HINT"]

COMMISSION_HINT = ("commission it from a record of it in good condition: hydromon commission RECORDING "
                   "--out RANGES.json")


@dataclass(frozen=True)
class RigRanges:
    """The ranges that grade a rig (None: none apply), their tag (what health's ``ranges`` says),
    and why none apply."""

    ranges: Ranges | None
    tag: str | None
    why: str | None = None


class RangesBook:
    """The default ranges and each rig's own, by rig id.

    Parameters
    ----------
    default : Ranges or None
        The ranges of every rig without its own (default ``Ranges.default()``, made for the
        reference rig); None: only rigs with their own ranges are graded.
    default_tag : str
        What a health graded on the default ranges says in its ``ranges`` field.
    """

    def __init__(self, default: Ranges | None = None, default_tag: str = "default"):
        self.default = Ranges.default() if default is None else default
        self.default_tag = default_tag
        self.rigs: dict[str, tuple[Ranges, str]] = {}

    def set(self, rig_id: str, ranges: Ranges, tag: str) -> None:
        """Rig ``rig_id`` has its own ranges from now on (tagged ``tag``)."""
        self.rigs[rig_id] = (ranges, tag)

    def remove(self, rig_id: str) -> None:
        self.rigs.pop(rig_id, None)

    def for_rig(self, rig_id: str, config: RigConfig | None) -> RigRanges:
        """The ranges that grade ``rig_id`` with constants ``config`` (None: the reference rig's)."""
        own = self.rigs.get(rig_id)
        if own is not None:
            why = own[0].made_for(config)
            if why is None:
                return RigRanges(own[0], own[1])
            return RigRanges(None, None, f"its ranges {own[1]} do not apply: {why}; {COMMISSION_HINT}")
        if self.default is not None:
            why = self.default.made_for(config)
            if why is None:
                return RigRanges(self.default, self.default_tag)
            return RigRanges(None, None, f"no ranges were made for it ({self.default_tag} ranges: {why}); "
                                         f"{COMMISSION_HINT}")
        return RigRanges(None, None, f"no ranges of its own; {COMMISSION_HINT}")
