"""What the monitor did with its input: counts by kind, for its exit summary and the bench."""

from __future__ import annotations

from dataclasses import dataclass, field

from hydromon.engine.validate import REJECT_REASONS

__all__ = ["MonitorCounters"]


@dataclass
class MonitorCounters:
    """What the monitor did with its input (all counts of messages, except ``missing``)."""

    accepted: int = 0          # samples fed to the estimators
    configs: int = 0           # valid config messages
    config_changes: int = 0    # configs that changed a known rig (its estimates restarted)
    rejected: dict = field(default_factory=lambda: {r: 0 for r in REJECT_REASONS})
    duplicate: int = 0         # seq equal to the last taken
    out_of_order: int = 0      # seq below the last taken
    ahead: int = 0             # seq far ahead, never followed by a run (hydromon.engine.sequence): dropped
    gaps: int = 0              # seq jumps
    missing: int = 0           # samples skipped by those jumps
    restarts: int = 0          # seq back to 0
    ignored: int = 0           # health, event and ranges messages (the monitors' own output)
    health: int = 0            # health messages produced
    stale_resent: int = 0      # latest health re-sent stale for a silent rig (MonitorCore.stale; not in as_dict)
    forgotten: int = 0         # rigs forgotten after a long silence (MonitorCore.forget; not in as_dict)
    configs_dropped: int = 0   # configs of rig ids without a row dropped for newer ones (max_rigs; not in as_dict)

    @property
    def dropped_seq(self) -> int:
        return self.duplicate + self.out_of_order + self.ahead

    @property
    def rejected_total(self) -> int:
        return sum(self.rejected.values())

    def as_dict(self) -> dict:
        return {"accepted": self.accepted, "configs": self.configs, "config_changes": self.config_changes,
                "rejected": dict(self.rejected), "duplicate": self.duplicate,
                "out_of_order": self.out_of_order, "ahead": self.ahead, "gaps": self.gaps, "missing": self.missing,
                "restarts": self.restarts, "ignored": self.ignored, "health": self.health}
