"""Grade one recording as the live monitor would: the pipeline over the whole record.

``evaluate`` returns an :class:`Evaluation` (``hydromon.store.recording.load_recording`` reads
and validates the record; ``hydromon.report.evaluate`` presents the result).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from hydromon.engine.record import Recording
from hydromon.engine.ranges_book import COMMISSION_HINT
from hydromon.engine.status import health_status
from monitor.grading import Ranges
from monitor.ident_options import IdentOptions
from monitor.evaluations import Assessment, Events
from monitor.pipeline import Pipeline
from hydromon.engine.frozen_watch import frozen_words
from hydromon.engine.stuck_watch import stuck_words
from monitor.audit.wiring import wiring_words
from monitor.readings import record_slip
from monitor.refine import Refinement, refine

__all__ = ["Evaluation", "evaluate"]



@dataclass(frozen=True)
class Evaluation:
    """The pipeline's assessment of a whole recording (the last evaluation)."""

    recording: Recording
    assessment: Assessment
    refined: Refinement | None = None  # the whole-record prediction-error fit, when asked for
    glitches: dict[str, int] | None = None  # sensor samples the outlier gate replaced, per sensor
    history: Events | None = None  # every evaluation of the run (sample index into the recording)
    ranges: Ranges | None = None  # the health ranges graded against (None: none made for the rig)
    x1_clamped: int = 0  # samples whose x1 would have emptied a chamber (config or x1 wrong)
    options: IdentOptions | None = None  # the identifier's options (None: defaults)
    uncalibrated: str | None = None  # why no ranges grade the rig (None: some do)
    units: str | None = None  # why the readings (glitches mended) cannot be in the config's units
    frozen: str | None = None  # why the readings cannot be trusted: they stopped changing (a stall, a stuck pressure)
    wiring: str | None = None  # why the sensors look wired wrong: a dead channel, exchanged pressures (grade withheld)

    @property
    def status(self) -> str:
        """``bad-input`` when an estimate is physically impossible (``monitor.plausibility``), x1
        went beyond a chamber's end or a reading cannot be in the config's units
        (``monitor.readings``) or the readings repeat one reading for 2 s
        (``hydromon.engine.frozen_watch``) or a chamber pressure holds one under a moving spool
        for 10 s (``hydromon.engine.stuck_watch``) or the sensors look wired wrong
        (``monitor.audit.wiring``; the grade is then withheld, ``unknown``), ``uncalibrated`` when
        no ranges were made for the rig's constants, ``ok`` once converged with a grade placed,
        else ``converging`` (the live monitor's statuses: a converged rig whose grade cannot be
        placed, level -1, is still converging)."""
        a = self.assessment
        return health_status(self.bad_input_words is not None, False, a.converged, a.level, self.uncalibrated is None)

    @property
    def bad_input_words(self) -> str | None:
        """Why the status is ``bad-input``, in words (None: it is not)."""
        a, why = self.assessment, []
        if a.implausible:
            why.append("physically impossible estimates (" + ", ".join(a.implausible) + ")")
        if self.x1_clamped:
            why.append(f"x1 beyond a chamber's end in {self.x1_clamped} samples")
        why += [w for w in (self.units, self.frozen, self.wiring) if w]
        return "; ".join(why) or None

    @property
    def memory_s(self) -> float | None:
        """The estimators' memory [s] it was graded with (``--memory``); None: a growing window."""
        return (self.options or IdentOptions()).memory_s(self.recording.config.sample_rate)


def evaluate(recording: Recording, ranges: Ranges | None = None,
             options: IdentOptions | None = None, refined: bool = False) -> Evaluation:
    """Run the monitor pipeline over the whole recording; the last assessment is the result.
    ``ranges`` (default ``Ranges.default()``) grade the record only if they were made for its
    rig constants; otherwise it is reported ungraded (``uncalibrated``, with why). With
    ``refined``, also fit the whole model to the record by prediction error (``monitor.refine``),
    started from the pipeline's estimates."""
    pipe = Pipeline(config=recording.config, options=options, ranges=ranges)
    events, assessment = pipe.run(recording.samples, recording.restarts)
    ref = _refine(recording, options, assessment) if refined else None
    why = pipe.fleet.why[0]
    wiring = wiring_words(recording.samples, recording.config, recording.restarts)
    if wiring is not None:  # every estimate came from the wrong wiring: a grade made of them would lie
        assessment = replace(assessment, level=-1, confidence=0.0,
                             param_levels=dict.fromkeys(assessment.param_levels, -1))
    return Evaluation(recording, assessment, ref, pipe.fleet.glitches(0), events,
                      pipe.fleet.ranges if why is None else None, pipe.fleet.x1_clamped(0), options,
                      uncalibrated=None if why is None else f"{why}; {COMMISSION_HINT}",
                      units=record_slip(recording.samples, recording.config, options, recording.restarts),
                      frozen=_frozen(recording), wiring=wiring)


def _frozen(recording: Recording) -> str | None:
    """Readings that stopped changing: all five channels (``hydromon.engine.frozen_watch``), else
    a chamber pressure under a moving spool (``hydromon.engine.stuck_watch``), as the live
    monitor flags them."""
    c = recording.config
    return frozen_words(recording.samples, c.sample_rate) or stuck_words(recording.samples, c.sample_rate, c.x5_span)


def _refine(recording: Recording, options: IdentOptions | None, assessment: Assessment) -> Refinement:
    """The whole-record fit (which sees what the streaming estimates saw: glitches replaced)
    over the longest stretch without a gap (the fit integrates the model from sample to sample)."""
    lo, hi = recording.longest_stretch()
    try:
        ref = refine(recording.samples[lo:hi], recording.config, assessment.params, options=options)
    except ValueError as exc:  # too short a stretch: the streaming evaluation still stands
        return Refinement(dict(assessment.params), dict.fromkeys(assessment.params, math.inf), False,
                          f"not run: {exc}")
    if recording.restarts:
        ref = replace(ref, message=f"{ref.message} (samples {lo}..{hi - 1}, the longest stretch without a gap)")
    return ref


