"""Model audit: identify the paper's model on a record, re-simulate it, and rank named extensions.

``audit(samples, config) -> AuditResult`` (pure); presenters are in ``hydromon.report.audit``.
"""

from .audit import AuditOptions, AuditResult, CandidateResult, audit
from .candidates import LIBRARY, Candidate

__all__ = ["audit", "AuditOptions", "AuditResult", "CandidateResult", "LIBRARY", "Candidate"]
