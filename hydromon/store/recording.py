"""One rig's record for ``evaluate`` and ``audit``: a CSV (t,ug,x1,x3,x4,x5 in SI) or an MCAP file,
read and validated as the live monitor would take it (the CSV/MCAP edge).

``load_recording`` reads and validates. A CSV: header, finite numbers, strictly increasing t,
sampling at the rig's rate within 1 % (a gap of whole sample periods is allowed and, as on
the bus, restarts the filters). An MCAP is taken as the live monitor takes it
(``hydromon.engine.sequence``): by ``seq``, not by time stamp (time stamps off the seq's grid are
counted, not refused); invalid samples, duplicate and out-of-order seqs are skipped and
counted; a seq jump is a gap; a rig config change restarts the estimates, so only the
samples after the last change are evaluated (the skipped ones are counted); a restart
(seq back to 0) is refused with a hint.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hydromon.contract import RigConfig
from hydromon.engine.record import Recording
from hydromon.engine.sequence import AHEAD, DUPLICATE, GAP, OUT_OF_ORDER, RESTART, sequence_order
from hydromon.store.csvfile import read_csv
from hydromon.store.sampling import check_sampling, check_seq_rate, time_jitter
from monitor.audit.wiring import dead_drive_words
from monitor.drive import command_for_drive

__all__ = ["Recording", "load_recording", "recording_rigs"]


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


def _take_drive(data: np.ndarray, u: np.ndarray, config: RigConfig, name: str) -> int:
    """Where a sample carries the valve drive u [V], make its command the one under which the
    rig constants' loop drives the valve with u (``monitor.drive``), in place in ``data``
    (columns t, ug, x1, ...); returns how many samples did. ValueError for a dead drive
    (``monitor.audit.wiring.dead_drive_words``): it would grade a valve that is not driven."""
    has = np.isfinite(u)
    why = dead_drive_words(u[has], data[has, 5], config)
    if why:
        raise ValueError(f"{name}: {why}")
    if has.any():
        data[has, 1] = command_for_drive(u[has], data[has, 2], config.K_p, config.K_f)
    return int(has.sum())


def _config_key(config: RigConfig) -> tuple:
    return tuple(config.model_dump().items())


def _named(name: str, exc: Exception) -> str:
    """The error's message, prefixed by the file's name unless it starts with it already."""
    msg = str(exc)
    return msg if msg.startswith(name) else f"{name}: {msg}"


def recording_rigs(path: str | Path, rig: str | None = None) -> list[str | None]:
    """The rigs an evaluation of ``path`` covers: ``[rig]`` when one is named, ``[None]`` for a
    CSV (one rig) or a file that cannot be listed (:func:`load_recording` then says why), else
    every rig whose samples an MCAP holds, by id."""
    path = Path(path)
    if rig is not None or path.suffix.lower() != ".mcap" or not path.is_file():
        return [rig]
    from hydromon.store import mcap_read

    try:
        rigs = mcap_read.sample_rigs(str(path))
    except (ValueError, OSError):
        return [None]
    return rigs if len(rigs) > 1 else [None]


def load_recording(path: str | Path, rig: str | None = None, config: RigConfig | None = None) -> Recording:
    """Read and validate one rig's samples from ``.csv`` or ``.mcap``.

    ``rig`` picks the rig of a multi-rig MCAP (a CSV holds one rig, called ``csv``). The rig
    constants are ``config`` if given (for the whole record), else the recording's (MCAP:
    those after the last config change, and only the samples after it are kept), else the
    defaults (the paper's rig, ``RigConfig()``). A sample's valve drive ``u``, where it has one,
    is the valve's input (``monitor.drive``).
    """
    path = Path(path)
    name = str(path)
    suffix = path.suffix.lower()
    if path.is_dir():
        raise ValueError(f"{name}: is a directory; give a recording (.csv or .mcap)")
    if path.exists() and not path.is_file():
        raise ValueError(f"{name}: not a regular file; give a recording (.csv or .mcap)")
    if suffix == ".csv":
        if rig is not None:
            raise ValueError("--rig selects a rig of an MCAP recording; a CSV holds one rig")
        drive: list[float] = []
        data = read_csv(path, drive=drive)
        config = config or RigConfig()
        restarts, missing = check_sampling(data[:, 0], config.sample_rate, lambda i: f"{name} line {i + 2}")
        driven = _take_drive(data, np.array(drive), config, name)
        return Recording("csv", data[:, 0].copy(), np.ascontiguousarray(data[:, 1:]), config, name,
                         tuple(restarts), missing, drive_samples=driven)
    if suffix == ".mcap":
        try:
            from hydromon.store import mcap_read
        except ImportError as exc:  # pragma: no cover - the module ships with hydromon
            raise ValueError(f"{name}: reading MCAP needs hydromon.store.mcap_read ({exc})") from None
        if not path.exists():
            raise FileNotFoundError(f"{name}: no such file")
        try:
            rejected: list[str] = []
            messages: list[tuple[int, RigConfig]] = []
            drive: list[float] = []
            bad_configs: list[str] = []
            rig_id, data, seq = mcap_read.read_samples(str(path), rig=rig, rejected=rejected, configs=messages,
                                                       drive=drive, bad_configs=bad_configs)
            stored = mcap_read.stored_configs(str(path), rig_id) if config is None else []
        except ValueError as exc:
            raise ValueError(_named(name, exc).replace("; choose one", "; choose one with --rig ID")) from None
        where = f"{name} rig {rig_id!r}"
        if bad_configs and config is None:
            # the live monitor keeps the constants it had (for a rig's first config: the reference
            # rig's) and says bad-input; a record graded on constants that are not the rig's is wrong
            more = f" (and {len(bad_configs) - 1} more)" if len(bad_configs) > 1 else ""
            raise ValueError(f"{where}: {bad_configs[0]}{more}; it is not graded on other constants: mend the "
                             "recording's config, or give the rig's constants with --config FILE")
        if len(data) == 0:
            why = f": all {len(rejected)} were invalid, the first {rejected[0]}" if rejected else ""
            raise ValueError(f"{name}: rig {rig_id!r} has no valid samples{why}")
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
        order, verdicts, dropped = sequence_order(seq)
        restarts = np.flatnonzero(verdicts == RESTART)  # positions in the order taken
        p0 = int(restarts[order[restarts] <= first].max(initial=0))
        later = restarts[restarts > p0]
        if later.size:  # one evaluation grades one run of the rig
            i = int(order[later[0]])
            raise ValueError(f"{where}: seq goes from {int(seq[order[p0]:i].max())} back to {int(seq[i])} at sample "
                             f"{i} (t = {float(data[i, 0])!r} s; the rig restarted): evaluate one run at a time, or "
                             "replay the recording (hydromon replay --direct), which handles restarts")
        s0 = int(order[p0])
        after = dropped[s0:]
        duplicate = int(np.sum(after == DUPLICATE))
        out_of_order = int(np.sum((after == OUT_OF_ORDER) | (after == AHEAD)))
        idx, v = order[p0:], verdicts[p0:]
        gaps_at = np.flatnonzero(v == GAP)
        # the seq tracking runs on through a config change, as live: a gap across it is counted
        missing = int(sum(int(seq[idx[g]] - seq[idx[g - 1]]) - 1 for g in gaps_at if g > 0))
        keep = idx >= first  # the estimates restart at the change: the samples before it are not graded
        shift = np.cumsum(~keep)  # samples left out up to each position
        # the estimates restart at the change anyway: a gap right there restarts nothing more
        restarts = [int(g - shift[g]) for g in gaps_at if keep[g] and g - shift[g] > 0]
        idx = idx[keep]
        data, seq = data[idx], seq[idx]
        check_seq_rate(data[:, 0], seq, config.sample_rate, where)
        driven = _take_drive(data, np.array(drive)[idx], config, name)
        jitter, jitter_max = time_jitter(data[:, 0], seq, config.sample_rate)
        return Recording(rig_id, data[:, 0].copy(), np.ascontiguousarray(data[:, 1:]), config, name,
                         tuple(restarts), missing, len(rejected), duplicate, out_of_order,
                         jitter, jitter_max, changes, first, driven)
    raise ValueError(f"{name}: unknown file type {path.suffix!r}; give a .csv (t,ug,x1,x3,x4,x5) or .mcap")


