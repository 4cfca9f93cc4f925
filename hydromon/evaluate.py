"""Grade one recording: a CSV (t,ug,x1,x3,x4,x5 in SI) or an MCAP file (the CSV/MCAP edge).

``load_recording`` reads and validates (header, finite numbers, strictly increasing t,
sampling at the rig's rate within 1 %; a gap of whole sample periods is allowed and, as on
the bus, restarts the filters; an MCAP's invalid samples are skipped and counted),
``evaluate`` runs the monitor pipeline
over the samples and returns an :class:`Evaluation`; ``to_json`` and ``render`` present it
(DESIGN.md section 6: ``{"grade", "level", "confidence", "status", "params", "std_errors"}``).
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from hydromon.contract import PARAM_NAMES, SAMPLE_LIMITS
from monitor.grading import Ranges
from monitor.ident_options import IdentOptions
from monitor.identify import V_MIN
from monitor.pipeline import Assessment, Events, Pipeline
from monitor.refine import REFINED, Refinement, refine
from plant_sim.params import RigConfig

__all__ = ["CSV_COLUMNS", "Recording", "Evaluation", "read_csv", "load_recording", "check_sampling",
           "evaluate", "to_json", "render", "csv_text", "PARAM_UNITS"]

CSV_COLUMNS = ("t", "ug", "x1", "x3", "x4", "x5")
RATE_TOL = 0.01  # allowed relative deviation of each sample interval from 1 / sample_rate

PARAM_UNITS = {
    "m": "kg", "B_fv": "N s/m", "f_c": "N", "K_t": "N/m", "inv_beta_e": "1/Pa",
    "CdW_sqrt_rho": "m^2.5/kg^0.5", "C_ip": "m^3/(s Pa)", "C_ep": "m^3/(s Pa)",
    "two_zeta_omega": "rad/s", "omega_sv2": "rad^2/s^2", "K_sv_omega_sv2": "m/(V s^2)",
    "K_sv": "m/V",
}


@dataclass(frozen=True)
class Recording:
    """One rig's validated samples: t (N,) [s], samples (N, 5) = ug [V], x1 [m], x3 [Pa],
    x4 [Pa], x5 [m]; the rig id and the rig constants the data were taken with."""

    rig: str
    t: np.ndarray
    samples: np.ndarray
    config: RigConfig
    source: str
    restarts: tuple[int, ...] = ()  # indices of samples that follow a gap
    missing: int = 0  # samples missing in those gaps
    rejected: int = 0  # invalid samples skipped (MCAP)


@dataclass(frozen=True)
class Evaluation:
    """The pipeline's assessment of a whole recording (the last evaluation)."""

    recording: Recording
    assessment: Assessment
    refined: Refinement | None = None  # the whole-record prediction-error fit, when asked for
    glitches: dict[str, int] | None = None  # sensor samples the outlier gate replaced, per sensor
    history: Events | None = None  # every evaluation of the run (sample index into the recording)
    ranges: Ranges | None = None  # the health ranges graded against
    x1_clamped: int = 0  # samples whose x1 would have emptied a chamber (config or x1 wrong)
    options: IdentOptions | None = None  # the identifier's options (None: defaults)

    @property
    def status(self) -> str:
        """``bad-input`` when an estimate is physically impossible (``monitor.plausibility``),
        ``ok`` once converged, else ``converging`` (the live monitor's statuses)."""
        if self.assessment.implausible:
            return "bad-input"
        return "ok" if self.assessment.converged else "converging"


def read_csv(src, name: str = "<csv>") -> np.ndarray:
    """Parse a CSV with header columns t,ug,x1,x3,x4,x5 (any order, extra columns ignored).

    src is a path or a text stream. Returns (N, 6) float64 in CSV_COLUMNS order. Raises
    ValueError naming the line of the first bad value (header = line 1).
    """
    if isinstance(src, (str, Path)):
        name = str(src)
        with open(src, newline="") as f:
            return read_csv(f, name)
    reader = csv.reader(src)
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise ValueError(f"{name}: empty file; expected a header {','.join(CSV_COLUMNS)}") from None
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:
        raise ValueError(f"{name} line 1: header {','.join(header)!r} lacks column(s) "
                         f"{', '.join(missing)}; expected {','.join(CSV_COLUMNS)} (SI units)")
    dup = sorted({c for c in CSV_COLUMNS if header.count(c) > 1})
    if dup:
        raise ValueError(f"{name} line 1: column(s) {', '.join(dup)} appear more than once")
    cols = [header.index(c) for c in CSV_COLUMNS]
    rows = []
    for row in reader:
        line = reader.line_num
        if not row or all(not c.strip() for c in row):
            raise ValueError(f"{name} line {line}: empty line")
        if len(row) != len(header):
            raise ValueError(f"{name} line {line}: {len(row)} fields, the header has {len(header)}")
        vals = []
        for c, j in zip(CSV_COLUMNS, cols):
            try:
                v = float(row[j])
            except ValueError:
                raise ValueError(f"{name} line {line}: {c} = {row[j]!r} is not a number") from None
            if not math.isfinite(v):
                raise ValueError(f"{name} line {line}: {c} = {row[j]!r} is not finite")
            if abs(v) > SAMPLE_LIMITS.get(c, math.inf):
                raise ValueError(f"{name} line {line}: {c} = {row[j]!r} is beyond the contract's limit "
                                 f"|{c}| <= {SAMPLE_LIMITS[c]:g} (SI units?)")
            vals.append(v)
        rows.append(vals)
    if not rows:
        raise ValueError(f"{name}: no samples after the header")
    return np.array(rows, dtype=np.float64)


def check_sampling(t: np.ndarray, sample_rate: float, where=lambda i: f"sample {i}") -> tuple[list[int], int]:
    """t [s] must increase strictly, every interval within RATE_TOL of a whole number of
    sample periods 1/sample_rate [Hz]. Returns the indices of samples after a gap (an
    interval of 2 periods or more) and the number of samples missing in the gaps.

    ``where(i)`` names sample i in the error (e.g. its CSV line).
    """
    h = 1.0 / sample_rate
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise ValueError(f"{where(i)}: t = {float(t[i])!r} s does not increase strictly "
                         f"(previous {float(t[i - 1])!r} s)")
    periods = np.rint(dt / h)
    bad = np.flatnonzero(np.abs(dt - periods * h) > RATE_TOL * h)
    if bad.size:
        i = int(bad[0]) + 1
        raise ValueError(f"{where(i)}: t = {float(t[i])!r} s is {float(dt[i - 1])!r} s after the previous "
                         f"sample; the rig samples every {h!r} s ({sample_rate:g} Hz, 1 % tolerance)")
    gaps = np.flatnonzero(periods > 1)
    return [int(i) + 1 for i in gaps], int(np.sum(periods[gaps] - 1))


def _seq_gaps(seq: np.ndarray, name: str) -> tuple[list[int], int]:
    """Samples after a gap in the rig's sequence numbers, and how many are missing."""
    d = np.diff(seq)
    back = np.flatnonzero(d <= 0)
    if back.size:
        i = int(back[0]) + 1
        raise ValueError(f"{name}: seq goes from {int(seq[i - 1])} back to {int(seq[i])} at sample {i} "
                         "(the rig restarted): evaluate one run at a time, or replay the recording "
                         "(hydromon replay --direct), which handles restarts")
    gaps = np.flatnonzero(d > 1)
    return [int(i) + 1 for i in gaps], int(np.sum(d[gaps] - 1))


def load_recording(path: str | Path, rig: str | None = None, config: RigConfig | None = None) -> Recording:
    """Read and validate one rig's samples from ``.csv`` or ``.mcap``.

    ``rig`` picks the rig of a multi-rig MCAP (a CSV holds one rig, called ``csv``). The rig
    constants are ``config`` if given, else the recording's (MCAP metadata), else the
    defaults (DESIGN.md section 5).
    """
    path = Path(path)
    name = str(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        if rig is not None:
            raise ValueError("--rig selects a rig of an MCAP recording; a CSV holds one rig")
        data = read_csv(path)
        config = config or RigConfig()
        restarts, missing = check_sampling(data[:, 0], config.sample_rate, lambda i: f"{name} line {i + 2}")
        return Recording("csv", data[:, 0].copy(), np.ascontiguousarray(data[:, 1:]), config, name,
                         tuple(restarts), missing)
    if suffix == ".mcap":
        try:
            from hydromon import mcap_io
        except ImportError as exc:  # pragma: no cover - the module ships with hydromon
            raise ValueError(f"{name}: reading MCAP needs hydromon.mcap_io ({exc})") from None
        if not path.exists():
            raise FileNotFoundError(f"{name}: no such file")
        try:
            rejected: list[str] = []
            rig_id, data, seq = mcap_io.read_samples(str(path), rig=rig, rejected=rejected)
        except ValueError as exc:
            hint = " (pick one with --rig ID)" if "several rigs" in str(exc) else ""
            raise ValueError(f"{name}: {exc}{hint}") from None
        if config is None:
            try:
                config = mcap_io.read_rig_config(str(path), rig_id)
            except ValueError:
                config = RigConfig()
        if len(data) == 0:
            raise ValueError(f"{name}: rig {rig_id!r} has no samples")
        bad = np.argwhere(~np.isfinite(data))
        if bad.size:
            raise ValueError(f"{name}: sample {int(bad[0, 0])} of rig {rig_id!r} is not finite")
        # gaps come from the sequence numbers (they also cover skipped invalid samples); the
        # time stamps must still sit on the rig's sample grid
        check_sampling(data[:, 0], config.sample_rate, lambda i: f"{name} rig {rig_id!r} sample {i}")
        restarts, missing = _seq_gaps(seq, f"{name} rig {rig_id!r}")
        return Recording(rig_id, data[:, 0].copy(), np.ascontiguousarray(data[:, 1:]), config, name,
                         tuple(restarts), missing, len(rejected))
    raise ValueError(f"{name}: unknown file type {path.suffix!r}; give a .csv (t,ug,x1,x3,x4,x5) or .mcap")


def evaluate(recording: Recording, ranges: Ranges | None = None,
             options: IdentOptions | None = None, refined: bool = False) -> Evaluation:
    """Run the monitor pipeline over the whole recording; the last assessment is the result.
    With ``refined``, also fit the whole model to the record by prediction error
    (``monitor.refine``), started from the pipeline's estimates."""
    pipe = Pipeline(config=recording.config, options=options, ranges=ranges)
    events, assessment = pipe.run(recording.samples, recording.restarts)
    ref = _refine(recording, options, assessment) if refined else None
    return Evaluation(recording, assessment, ref, pipe.fleet.glitches(0), events, pipe.fleet.ranges,
                      pipe.fleet.x1_clamped(0), options)


def _refine(recording: Recording, options: IdentOptions | None, assessment: Assessment) -> Refinement:
    """The whole-record fit (which sees what the streaming estimates saw: glitches replaced)
    over the longest stretch without a gap (the fit integrates the model from sample to sample)."""
    bounds = [0, *recording.restarts, len(recording.samples)]
    lo, hi = max(zip(bounds[:-1], bounds[1:]), key=lambda b: b[1] - b[0])
    try:
        ref = refine(recording.samples[lo:hi], recording.config, assessment.params, options=options)
    except ValueError as exc:  # too short a stretch: the streaming evaluation still stands
        return Refinement(dict(assessment.params), dict.fromkeys(assessment.params, math.inf), False,
                          f"not run: {exc}")
    if recording.restarts:
        ref = replace(ref, message=f"{ref.message} (samples {lo}..{hi - 1}, the longest stretch without a gap)")
    return ref


def _num(v: float):
    return float(v) if math.isfinite(v) else None


def to_json(ev: Evaluation) -> dict:
    """The ``evaluate --json`` document: DESIGN.md section 6's keys (plus ``refined`` when the
    refinement ran); non-finite numbers (an unidentified parameter's standard error is inf)
    become null."""
    a = ev.assessment
    out = {
        "grade": a.grade,
        "level": a.level if a.level >= 0 else None,
        "confidence": float(a.confidence),
        "status": ev.status,
        "params": {k: _num(a.params[k]) for k in PARAM_NAMES},
        "std_errors": {k: _num(a.std_errors[k]) for k in PARAM_NAMES},
    }
    if ev.glitches is not None:  # added keys
        out["glitches_replaced"] = ev.glitches
    out["x1_outside_chambers"] = ev.x1_clamped
    out["implausible"] = list(a.implausible)  # impossible estimates: the grade is withheld
    rec = ev.recording
    out["gaps"] = {"count": len(rec.restarts), "missing_samples": rec.missing, "rejected_samples": rec.rejected}
    if ev.refined is not None:  # an added key (DESIGN.md 6: add more freely)
        r = ev.refined
        out["refined"] = {"ok": r.ok, "message": r.message,
                          "params": {k: _num(r.params[k]) for k in REFINED},
                          "std_errors": {k: _num(r.std_errors[k]) for k in REFINED},
                          "sensor_noise": r.noise}
    return out


def render(ev: Evaluation, console=None) -> None:
    """Print the evaluation as a readable table (rich)."""
    from rich.console import Console
    from rich.table import Table

    console = console or Console()
    a = ev.assessment
    r = ev.recording
    dur = len(r.samples) / r.config.sample_rate
    console.print(f"[bold]{r.source}[/bold]  rig {r.rig}: {len(r.samples)} samples, {dur:g} s")
    level = "unknown" if a.level < 0 else str(a.level)
    console.print(f"grade [bold]{a.grade}[/bold]  level {level}  confidence {a.confidence:.3f}  "
                  f"status {ev.status}")
    t = Table(show_header=True, header_style="bold")
    ref = ev.refined
    cols = [("parameter", "left"), ("value", "right"), ("std error", "right")]
    if ref is not None:
        cols += [("refined", "right"), ("std error ", "right")]
    for col, just in cols + [("unit", "left"), ("grade", "left")]:
        t.add_column(col, justify=just)
    grades = a.param_grades
    for k in PARAM_NAMES:
        row = [k, f"{a.params[k]:.5g}", f"{a.std_errors[k]:.3g}"]
        if ref is not None:
            row += [f"{ref.params[k]:.5g}", f"{ref.std_errors[k]:.3g}"] if k in REFINED else ["", ""]
        t.add_row(*row, PARAM_UNITS[k], grades.get(k, ""))
    console.print(t)
    graded = ev.ranges.params if ev.ranges is not None else {}
    if "K_sv" in graded and "K_sv_omega_sv2" not in graded:
        w2, s = a.params["omega_sv2"], a.std_errors["omega_sv2"]
        how = (f"here omega^2 +-{100 * s / abs(w2):.2g} %" if math.isfinite(s) and math.isfinite(w2) and w2
               else "here omega^2 has no SE")
        console.print(f"[dim]the valve is graded on its static gain K_sv; K_sv omega^2 is reported, not graded: it "
                      f"needs the valve's dynamics excited, which a record that starts mid-run on a smooth command "
                      f"lacks ({how}); --ranges paper grades it as Table 3 prints it[/dim]")
    if r.restarts or r.rejected:
        console.print(f"[yellow]{len(r.restarts)} gap(s), {r.missing} sample(s) missing, {r.rejected} invalid "
                      "sample(s) skipped: the filters restarted after each gap, the estimates carried on[/yellow]")
    if a.implausible:
        what = ", ".join(f"{k} = {a.params[k]:.3g} (SE {a.std_errors[k]:.2g})" for k in a.implausible)
        console.print(f"[red]not graded: physically impossible estimates ({what}; each must be positive). The "
                      "record does not obey the model: check the units (SI: m, Pa, V), the signs and zeros of x1, "
                      "x3, x4, x5 and ug, and the rig constants[/red]")
    if ev.x1_clamped:
        c = r.config
        lo, hi = -(1 - V_MIN) * c.V10 / c.A1, (1 - V_MIN) * c.V20 / c.A2
        console.print(f"[red]{ev.x1_clamped} sample(s) put x1 at a chamber's end (x1 < {lo:.4g} m or > {hi:.4g} m "
                      "leaves a chamber under 1 % of its volume V_i0): the rig constants or x1's zero, sign or "
                      "unit are wrong, and the chamber parameters are not to be trusted[/red]")
    if ev.glitches and any(ev.glitches.values()):
        what = ", ".join(f"{n} {k}" for k, n in ev.glitches.items() if n)
        console.print(f"[yellow]sensor glitches replaced by their neighbours' mean: {what}[/yellow]")
    if ref is not None:
        console.print(f"refined: whole-record prediction-error fit, {'ok' if ref.ok else 'FAILED'}: {ref.message}; "
                      "the grade is the streaming pipeline's")


def csv_text(t: np.ndarray, samples: np.ndarray) -> str:
    """CSV text that :func:`read_csv` reads back exactly: header CSV_COLUMNS, t [s] (N,) and
    samples (N, 5) [SI] at full precision."""
    out = io.StringIO()
    out.write(",".join(CSV_COLUMNS) + "\n")
    for ti, row in zip(t, samples):
        out.write(",".join(repr(float(v)) for v in (ti, *row)) + "\n")
    return out.getvalue()
