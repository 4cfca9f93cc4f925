"""One rig's record for ``evaluate`` and ``audit``: a CSV (t,ug,x1,x3,x4,x5 in SI) or an MCAP file,
read and validated as the live monitor would take it (the CSV/MCAP edge).

``load_recording`` reads and validates. A CSV: header, finite numbers, strictly increasing t,
sampling at the rig's rate within 1 % (a gap of whole sample periods is allowed and, as on
the bus, restarts the filters). An MCAP is taken as the live monitor takes it
(hydromon/monitorcore.py): by ``seq``, not by time stamp (time stamps off the seq's grid are
counted, not refused); invalid samples, duplicate and out-of-order seqs are skipped and
counted; a seq jump is a gap; a rig config change restarts the estimates, so only the
samples after the last change are evaluated (the skipped ones are counted); a restart
(seq back to 0) is refused with a hint.
"""

from __future__ import annotations

import csv
import math
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hydromon.contract import RESTART_RUN, SAMPLE_COLUMNS, SAMPLE_LIMITS
from plant_sim.params import RigConfig

__all__ = ["CSV_COLUMNS", "RATE_TOL", "Recording", "read_csv", "load_recording", "check_increasing",
           "check_sampling", "csv_text"]

CSV_COLUMNS = SAMPLE_COLUMNS  # a CSV record has the sample payload's columns
RATE_TOL = 0.01  # allowed relative deviation of each sample interval from 1 / sample_rate
# the median interval further than this from one period [relative] means another rate or unit
# (a quarter, not a half: 200 Hz sits at half a period, where rounding goes either way)
TYPICAL_TOL = 0.25

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
    duplicate: int = 0  # samples dropped for a seq equal to the last one taken (MCAP)
    out_of_order: int = 0  # samples dropped for a seq below the last one taken (MCAP)
    jitter: int = 0  # intervals whose time stamps are off their seq step by > RATE_TOL (MCAP)
    jitter_max: float = 0.0  # the largest disagreement of those intervals [s]
    config_changes: int = 0  # rig config changes in the record (MCAP)
    skipped: int = 0  # samples before the last config change, not evaluated

    @property
    def duration(self) -> float:
        """The span the samples cover [s]: first to last sample plus one period, gaps included."""
        return (len(self.samples) + self.missing) / self.config.sample_rate

    def longest_stretch(self) -> tuple[int, int]:
        """``(lo, hi)``: samples[lo:hi] is the longest stretch without a gap (the first of equals)."""
        bounds = [0, *self.restarts, len(self.samples)]
        return max(zip(bounds[:-1], bounds[1:]), key=lambda b: b[1] - b[0])


def read_csv(src, name: str = "<csv>") -> np.ndarray:
    """Parse a CSV with header columns t,ug,x1,x3,x4,x5 (any order, extra columns ignored).

    src is a path or a text stream. Returns (N, 6) float64 in CSV_COLUMNS order. Raises
    ValueError naming the line of the first bad value (header = line 1); a missing file raises
    FileNotFoundError naming it. A UTF-8 byte order mark before the header is allowed.
    """
    if isinstance(src, (str, Path)):
        text = _read_text(Path(src))
        try:
            return read_csv(io.StringIO(text, newline=""), str(src))
        except ValueError as exc:
            last = text.count("\n") + 1  # the line number of an unterminated last line
            if text and not text.endswith(("\n", "\r")) and f" line {last}:" in str(exc):
                raise ValueError(f"{exc}; it is the last line and has no line end: was the file cut short "
                                 "(a logger stopped mid-write)? Remove that line") from None
            raise
    reader = csv.reader(src)
    try:
        first = next(reader)
    except StopIteration:
        raise ValueError(f"{name}: empty file; expected a header {','.join(CSV_COLUMNS)}") from None
    if first:  # Excel's "CSV UTF-8" starts with a byte order mark
        first[0] = first[0].removeprefix("\ufeff")
    header = [h.strip() for h in first]
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:
        raise ValueError(f"{name} line 1: header {','.join(header)!r} lacks column(s) "
                         f"{', '.join(missing)}; expected {','.join(CSV_COLUMNS)} (SI units)")
    dup = sorted({c for c in CSV_COLUMNS if header.count(c) > 1})
    if dup:
        raise ValueError(f"{name} line 1: column(s) {', '.join(dup)} appear more than once")
    cols = [header.index(c) for c in CSV_COLUMNS]
    rows = []
    blank = None  # the first blank line seen: an error only if a row follows it
    for row in reader:
        line = reader.line_num
        if not row or all(not c.strip() for c in row):
            blank = blank or line
            continue
        if blank is not None:
            raise ValueError(f"{name} line {blank}: empty line")
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


def _read_text(path: Path) -> str:
    """A CSV file's text; every error names the file (and the line of a byte that is not UTF-8)."""
    name = str(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise FileNotFoundError(f"{name}: no such file") from None
    except OSError as exc:
        raise ValueError(f"{name}: cannot be read ({exc.strerror or exc})") from None
    try:
        return data.decode("utf-8")  # not utf-8-sig: its error offsets leave out the mark; read_csv drops it
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise ValueError(f"{name} line {line}: byte {data[exc.start]:#04x} is not UTF-8 text; expected a CSV "
                         f"with the header {','.join(CSV_COLUMNS)} (is it a binary file?)") from None


def _rate_hint(typical: float, h: float, sample_rate: float) -> str:
    """What a typical interval ``typical`` [s] other than the period ``h`` [s] most likely means."""
    for factor, unit in ((1e3, "milliseconds"), (1e6, "microseconds"), (1e9, "nanoseconds")):
        if abs(typical / (factor * h) - 1) <= RATE_TOL:
            return f"t looks like {unit}; give t in seconds (SI)"
    return f"the file looks sampled at {1 / typical:.4g} Hz, not {sample_rate:g} Hz (or t is not in seconds)"


def check_increasing(t: np.ndarray, where=lambda i: f"sample {i}") -> np.ndarray:
    """The intervals of ``t`` [s], which must increase strictly (ValueError naming the first
    sample that does not, by ``where(i)``)."""
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise ValueError(f"{where(i)}: t = {float(t[i])!r} s does not increase strictly "
                         f"(previous {float(t[i - 1])!r} s)")
    return dt


def check_sampling(t: np.ndarray, sample_rate: float, where=lambda i: f"sample {i}") -> tuple[list[int], int]:
    """t [s] must increase strictly, the median interval must be one sample period
    1/sample_rate [Hz] (within TYPICAL_TOL), and every interval within RATE_TOL of a whole
    number of periods.
    Returns the indices of samples after a gap (an interval of 2 periods or more) and the
    number of samples missing in the gaps.

    ``where(i)`` names sample i in the error (e.g. its CSV line).
    """
    h = 1.0 / sample_rate
    dt = check_increasing(t, where)
    if not dt.size:
        return [], 0
    periods = np.rint(dt / h)
    typical = float(np.median(dt))
    if abs(typical / h - 1) > TYPICAL_TOL:
        # another rate or unit: every interval may still be a whole number of periods (t in ms:
        # 1000 each), which would pass below as a record of nothing but gaps
        off = np.flatnonzero(periods != 1)
        i = int(off[0]) + 1 if off.size else 1
        raise ValueError(f"{where(i)}: t = {float(t[i])!r} s is {float(dt[i - 1])!r} s after the previous sample, "
                         f"and the median interval is {typical:.6g} s, but the rig samples every {h!r} s "
                         f"({sample_rate:g} Hz): {_rate_hint(typical, h, sample_rate)}")
    bad = np.flatnonzero(np.abs(dt - periods * h) > RATE_TOL * h)
    if bad.size:
        i = int(bad[0]) + 1
        raise ValueError(f"{where(i)}: t = {float(t[i])!r} s is {float(dt[i - 1])!r} s after the previous "
                         f"sample; the rig samples every {h!r} s ({sample_rate:g} Hz, 1 % tolerance)")
    gaps = np.flatnonzero(periods > 1)
    return [int(i) + 1 for i in gaps], int(np.sum(periods[gaps] - 1))


def _seq_taken(seq: np.ndarray, t: np.ndarray, name: str, first: int = 0) -> tuple[np.ndarray, int, int]:
    """``(taken, duplicate, out_of_order)``: which samples the live monitor takes
    (hydromon/monitorcore.py), those whose seq is above every seq before it, and how many it
    drops: a seq equal to the last taken is a duplicate, a lower one out of order. Seq 0 after
    a higher seq is the rig restarting: refused (ValueError), since one evaluation grades one
    run. ``first`` is sample 0's index in the file (for the error)."""
    last = np.maximum.accumulate(seq)  # the last seq taken is the highest so far: drops are below it
    before = np.r_[-1, last[:-1]]
    back = _restarts(seq)
    if back:
        i = back[0]
        raise ValueError(f"{name}: seq goes from {int(before[i])} back to {int(seq[i])} at sample {first + i} "
                         f"(t = {float(t[i])!r} s; the rig restarted): evaluate one run at a time, or replay "
                         "the recording (hydromon replay --direct), which handles restarts")
    return seq > before, int(np.sum(seq == before)), int(np.sum(seq < before))


def _restarts(seq: np.ndarray) -> list[int]:
    """Indices where the live monitor sees the rig restart: seq 0 after a higher seq taken (a
    second seq 0 right after a restart is a duplicate, not another restart), or the
    ``RESTART_RUN``-th of a run of seqs below the last one taken, each above the one before (a
    restart whose first samples were lost; hydromon/monitorcore.py)."""
    out, last, run, prev = [], -1, 0, -1
    for i, s in enumerate(seq.tolist()):
        if 0 < s < last:
            run, prev = (run + 1 if run and prev < s else 1), s
        if s == 0 and last > 0 or 0 < s < last and run >= RESTART_RUN:
            out.append(i)
            last, run = s, 0
        elif s > last:
            last, run = s, 0
    return out


def _seq_gaps(seq: np.ndarray) -> tuple[list[int], int]:
    """Samples after a gap in the rig's (increasing) sequence numbers, and how many are missing."""
    d = np.diff(seq)
    gaps = np.flatnonzero(d > 1)
    return [int(i) + 1 for i in gaps], int(np.sum(d[gaps] - 1))


def _time_jitter(t: np.ndarray, seq: np.ndarray, sample_rate: float) -> tuple[int, float]:
    """Intervals whose time stamps disagree with their seq step by more than RATE_TOL of a
    period, and the largest of those disagreements [s] (0 if none). The monitor goes by seq and
    never reads t, so this is reported, not refused."""
    off = np.abs(np.diff(t) - np.diff(seq) / sample_rate)
    bad = off[off > RATE_TOL / sample_rate]
    return int(bad.size), float(bad.max()) if bad.size else 0.0


def _after_last_change(messages: list[tuple[int, RigConfig]], stored: list[RigConfig], n: int,
                       name: str) -> tuple[RigConfig, int, int]:
    """``(config, first, changes)``: the rig constants of the samples from index ``first`` on,
    after the last of ``changes`` config changes among ``n`` samples.

    ``messages`` are the rig's config messages as ``(index of the next sample, config)``;
    ``stored`` its configs stored as metadata (the first is the one in force when the file
    began). As the live monitor does, a config that differs from the one in force after the
    rig's first sample restarts its estimates: the samples before it were taken with other
    constants, so they are not evaluated with these.
    """
    if not messages and len(set(map(_config_key, stored))) > 1:
        raise ValueError(f"{name}: {len(stored)} different configs stored for the rig as metadata, but no "
                         "config messages: cannot tell which samples each applies to")
    # a part the recorder opened carries the rigs' configs as messages ahead of its first one; a
    # config stored as metadata only (an older recording) is the one in force from its start; else
    # the monitor's defaults, and the first config message after a sample is a change (the live
    # monitor had none before it either)
    current = stored[0] if stored and not messages else RigConfig()
    # a monitor runs at one sample rate and rejects configs of another (MonitorCore._on_config):
    # the record's rate is its first config's
    rate = (messages[0][1] if messages else current).sample_rate
    first = changes = 0
    for i, config in messages:
        if i >= n:  # after the last sample: no sample was taken with it
            break
        if config.sample_rate != rate:
            continue
        if i > 0 and config != current:
            first, changes = i, changes + 1
        current = config
    return current, first, changes


def _config_key(config: RigConfig) -> tuple:
    return tuple(config.model_dump().items())


def _named(name: str, exc: Exception) -> str:
    """The error's message, prefixed by the file's name unless it starts with it already."""
    msg = str(exc)
    return msg if msg.startswith(name) else f"{name}: {msg}"


def load_recording(path: str | Path, rig: str | None = None, config: RigConfig | None = None) -> Recording:
    """Read and validate one rig's samples from ``.csv`` or ``.mcap``.

    ``rig`` picks the rig of a multi-rig MCAP (a CSV holds one rig, called ``csv``). The rig
    constants are ``config`` if given (for the whole record), else the recording's (MCAP:
    those after the last config change, and only the samples after it are kept), else the
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
            messages: list[tuple[int, RigConfig]] = []
            rig_id, data, seq = mcap_io.read_samples(str(path), rig=rig, rejected=rejected, configs=messages)
            stored = mcap_io.stored_configs(str(path), rig_id) if config is None else []
        except ValueError as exc:
            raise ValueError(_named(name, exc).replace("; choose one", "; choose one with --rig ID")) from None
        where = f"{name} rig {rig_id!r}"
        if len(data) == 0:
            raise ValueError(f"{name}: rig {rig_id!r} has no samples")
        bad = np.argwhere(~np.isfinite(data))
        if bad.size:
            raise ValueError(f"{name}: sample {int(bad[0, 0])} of rig {rig_id!r} is not finite")
        first = changes = 0
        if config is None:
            config, first, changes = _after_last_change(messages, stored, len(data), where)
        # by seq, as the live monitor: it restarts the filters at a seq jump (which also covers
        # skipped invalid samples) and never reads t, so t off the grid is counted, not refused.
        # Its seq tracking runs on through a config change (a duplicate of the last seq before the
        # change is dropped after it, a gap across it counted); only a rig restart resets it
        s0 = max((i for i in _restarts(seq) if i <= first), default=0)
        taken, duplicate, out_of_order = _seq_taken(seq[s0:], data[s0:, 0], where, s0)
        idx = s0 + np.flatnonzero(taken)
        gaps_at, missing = _seq_gaps(seq[idx])
        n_before = int(np.sum(idx < first))
        # the estimates restart at the change anyway: a gap right there restarts nothing more
        restarts = [i - n_before for i in gaps_at if i - n_before > 0]
        idx = idx[n_before:]
        data, seq = data[idx], seq[idx]
        jitter, jitter_max = _time_jitter(data[:, 0], seq, config.sample_rate)
        return Recording(rig_id, data[:, 0].copy(), np.ascontiguousarray(data[:, 1:]), config, name,
                         tuple(restarts), missing, len(rejected), duplicate, out_of_order,
                         jitter, jitter_max, changes, first)
    raise ValueError(f"{name}: unknown file type {path.suffix!r}; give a .csv (t,ug,x1,x3,x4,x5) or .mcap")


def csv_text(t: np.ndarray, samples: np.ndarray) -> str:
    """CSV text that :func:`read_csv` reads back exactly: header CSV_COLUMNS, t [s] (N,) and
    samples (N, 5) [SI] at full precision."""
    out = io.StringIO()
    out.write(",".join(CSV_COLUMNS) + "\n")
    for ti, row in zip(t, samples):
        out.write(",".join(repr(float(v)) for v in (ti, *row)) + "\n")
    return out.getvalue()
