"""A monitor core's state as numbers and JSON, and back: what a restarted monitor resumes from.

:func:`snapshot` takes every rig's whole state from a :class:`~hydromon.engine.core.MonitorCore`
between two ``process`` calls: its estimator row (``monitor.layout``), its grading hysteresis, its
sequence state (last seq, samples since a restart or gap), its units watch's counts
(``hydromon.engine.units_watch``), its announced grade and status, its
latest health, and the config it sent (a rig sends its config once, so a restarted monitor that
forgot it would grade the rig on the wrong constants). :func:`encode` writes it as an ``.npz``
archive of plain arrays plus one JSON document (read back with ``allow_pickle=False``: no code
runs on load), versioned twice: :data:`FORMAT` for this file's own layout and
``monitor.layout.LAYOUT_VERSION`` for the estimator rows inside it.

:func:`restore` puts it into a fresh core. What the core does next is what it does after any gap:
the rig's next sample is a seq jump, its filters restart, the estimates and the grade carry on,
and its health says ``stale`` until ``stale_samples`` samples have followed. So a core restored
from a checkpoint gives byte for byte the health of one that ran on without a break but lost the
same samples (a test). A checkpoint is refused whole when its format or estimator layout differs
or the monitor runs with other estimator settings; one rig is refused when its saved constants
differ from what its saved config gives now. Nothing is half-loaded: every check runs before the
core is touched.
"""

from __future__ import annotations

import hashlib
import io
from dataclasses import dataclass

import numpy as np
import orjson

from hydromon.contract import RigConfig
from hydromon.engine.rig_table import ROW_STATE
from monitor.layout import LAYOUT_VERSION

__all__ = ["FORMAT", "Checkpoint", "CheckpointRefused", "decode", "encode", "restore", "snapshot"]

FORMAT = 2
"""Version of the checkpoint file itself (its arrays and JSON fields). Format 1 is read too: it
lacks the units watch's three columns, which restore as a rig's fresh values (no samples beyond
its bounds counted, no warning given)."""

# the core's per-row sequence state saved with each rig (``hydromon.engine.rig_table.ROW_STATE``);
# ``_holding`` is not: samples held back are not saved, they are part of the gap
_ROW_FIELDS = ("_last", "_n", "_gap", "_bad", "_clamp_warned", "_back_n", "_back_seq", "_back_warned",
               "_units", "_units_windows", "_units_warned")
_FORMAT_1_FIELDS = 8  # format 1 held the first eight: the sequence state
_FIELDS_OF = {1: _FORMAT_1_FIELDS, FORMAT: len(_ROW_FIELDS)}  # the columns of ``rows`` in each format read


class CheckpointRefused(ValueError):
    """The checkpoint cannot be restored into this core (the message says why)."""


@dataclass(frozen=True)
class Checkpoint:
    """A core's state: ``meta`` (JSON-able) and per-rig arrays (row ``i`` is ``meta['rigs'][i]``).

    Attributes
    ----------
    meta : dict
        ``format``, ``layout``, ``settings`` (the core's estimator settings digest, sample rate
        [Hz], eval_every), ``rigs`` (ids), ``configs`` (every config the core holds, by rig id),
        ``tags`` (the ranges each rig was graded on), ``latest`` (latest health JSON per rig),
        ``announced`` (per rig: [[level, status] or null, [level, status] or null, count]).
    states, consts, bands : np.ndarray
        The rigs' estimator rows, constants rows and grading hysteresis (``monitor.pipeline.Fleet``).
    counts : np.ndarray
        Samples each rig's estimator has taken (int64).
    rows : np.ndarray
        The core's sequence state per rig, columns :data:`_ROW_FIELDS` (int64).
    """

    meta: dict
    states: np.ndarray
    consts: np.ndarray
    bands: np.ndarray
    counts: np.ndarray
    rows: np.ndarray

    @property
    def rigs(self) -> list[str]:
        return list(self.meta["rigs"])


def _settings(core) -> dict:
    """What the saved estimator rows depend on besides the layout: the same rows mean other
    things under other hyperparameters or another sample rate."""
    fleet = core.fleet
    options = fleet.options.model_dump_json().encode()
    return {"options": hashlib.sha256(options).hexdigest()[:16], "sample_rate": fleet.sample_rate,
            "eval_every": core.eval_every, "stale_samples": core.stale_samples, "stagger": fleet.stagger,
            "grade_z": fleet.grade_z, "grade_margin": fleet.grade_margin}


def snapshot(core) -> Checkpoint:
    """Every rig's state in ``core`` (a copy; call between ``process`` calls)."""
    fleet = core.fleet
    ids = [rig_id for rig_id in fleet.ids if rig_id in core.rigs]
    rows = np.array([core.rigs[rig_id].row for rig_id in ids], dtype=np.int64)
    ann = core.verdicts.announcer
    announced = []
    for r in rows.tolist():
        ann._grow(r)
        announced.append([ann._announced[r], ann._candidate[r], ann._count[r]])
    meta = {
        "format": FORMAT, "layout": LAYOUT_VERSION, "settings": _settings(core), "rigs": ids,
        "configs": {rig_id: c.model_dump() for rig_id, c in core.configs.items()},
        "tags": [fleet.ranges_tag(r) for r in rows.tolist()],
        "latest": [core.latest[rig_id].decode() if rig_id in core.latest else None for rig_id in ids],
        "announced": announced,
    }
    seq_state = np.stack([getattr(core, name)[rows].astype(np.int64) for name in _ROW_FIELDS], axis=1) \
        if len(ids) else np.zeros((0, len(_ROW_FIELDS)), dtype=np.int64)
    return Checkpoint(meta, fleet.states[rows].copy(), fleet.consts[rows].copy(), fleet.bands[rows].copy(),
                      fleet.counts[rows].copy(), seq_state)


def encode(ckpt: Checkpoint) -> bytes:
    """The checkpoint as the bytes of an ``.npz`` archive (no pickled objects)."""
    buf = io.BytesIO()
    np.savez(buf, meta=np.frombuffer(orjson.dumps(ckpt.meta), dtype=np.uint8), states=ckpt.states,
             consts=ckpt.consts, bands=ckpt.bands, counts=ckpt.counts, rows=ckpt.rows)
    return buf.getvalue()


def decode(data: bytes) -> Checkpoint:
    """A checkpoint from :func:`encode`'s bytes; :class:`CheckpointRefused` when they are not one
    of this format and estimator layout."""
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            arrays = {k: z[k] for k in ("meta", "states", "consts", "bands", "counts", "rows")}
        meta = orjson.loads(arrays.pop("meta").tobytes())
    except Exception as exc:  # numpy and zipfile raise many kinds on a damaged archive
        raise CheckpointRefused(f"not a readable checkpoint ({type(exc).__name__}: {exc})") from None
    if not isinstance(meta, dict) or meta.get("format") not in _FIELDS_OF:
        raise CheckpointRefused(f"checkpoint format {meta.get('format') if isinstance(meta, dict) else '?'}; "
                                f"this monitor reads formats {', '.join(map(str, sorted(_FIELDS_OF)))}")
    if meta.get("layout") != LAYOUT_VERSION:
        raise CheckpointRefused(f"estimator state layout {meta.get('layout')}; this monitor's is {LAYOUT_VERSION} "
                                "(saved by another version of hydromon)")
    n = len(meta.get("rigs", ()))
    if any(len(a) != n for a in arrays.values()) or arrays["rows"].shape[1:] != (_FIELDS_OF[meta["format"]],):
        raise CheckpointRefused("checkpoint arrays disagree with its list of rigs")
    rows = arrays["rows"]
    if rows.shape[1] < len(_ROW_FIELDS):  # an older format: the missing columns as a new rig's
        fresh = {name: value for name, value, _ in ROW_STATE}
        rest = np.array([int(fresh[name]) for name in _ROW_FIELDS[rows.shape[1]:]], dtype=np.int64)
        arrays["rows"] = np.concatenate([rows, np.tile(rest, (n, 1))], axis=1)
    return Checkpoint({**meta, "format": FORMAT}, **arrays)


def restore(core, ckpt: Checkpoint) -> list[tuple[str, str]]:
    """Put the checkpoint's rigs into ``core`` (one that holds none of them yet).

    Returns ``(rig id, why)`` for each rig refused (it starts afresh when it sends samples).
    Raises :class:`CheckpointRefused` (core untouched) when the core's estimator settings
    (identifier options, sample rate [Hz], evaluation and grading settings) differ from the
    checkpoint's, or a rig is already in the core.
    """
    meta = ckpt.meta
    settings = _settings(core)
    if meta["settings"] != settings:
        diff = sorted(k for k in settings if meta["settings"].get(k) != settings[k])
        raise CheckpointRefused(f"saved by a monitor with other estimator settings ({', '.join(diff)})")
    ids = meta["rigs"]
    if any(rig_id in core.rigs for rig_id in ids):
        raise CheckpointRefused("the monitor already holds some of its rigs")
    configs = {}
    for rig_id, c in meta["configs"].items():
        try:
            configs[rig_id] = RigConfig.model_validate(c)
        except ValueError as exc:
            raise CheckpointRefused(f"rig {rig_id}: its saved config is not valid ({exc})") from None
    refused, take = [], []
    fleet = core.fleet
    from monitor.ident_options import rig_constants  # the same constants a rig added now would get
    for i, rig_id in enumerate(ids):
        expect = rig_constants(configs.get(rig_id) or RigConfig())
        if not np.array_equal(expect, ckpt.consts[i]):
            refused.append((rig_id, "its saved constants differ from what its saved config gives"))
        else:
            take.append(i)
    if len(core.rigs) + len(take) > core.max_rigs:
        raise CheckpointRefused(f"{len(take)} rigs, more than this monitor's --max-rigs {core.max_rigs}")
    core.configs.update(configs)
    ann = core.verdicts.announcer
    for i in take:
        rig_id = ids[i]
        r = core._rig(rig_id).row
        fleet.states[r] = ckpt.states[i]
        fleet.counts[r] = ckpt.counts[i]
        if meta["tags"][i] == fleet.ranges_tag(r):  # hysteresis of the same ranges; other ranges grade afresh
            fleet.bands[r] = ckpt.bands[i]
        for j, name in enumerate(_ROW_FIELDS):
            arr = getattr(core, name)
            arr[r] = ckpt.rows[i, j]
        a, cand, count = meta["announced"][i]
        ann._grow(r)
        ann._announced[r] = None if a is None else (int(a[0]), str(a[1]))
        ann._candidate[r] = None if cand is None else (int(cand[0]), str(cand[1]))
        ann._count[r] = int(count)
        if meta["latest"][i] is not None:
            core.latest[rig_id] = meta["latest"][i].encode()
    for rig_id in configs:  # configs of rigs that send no sample yet, oldest first as saved
        if rig_id not in core.rigs:
            core._unused[rig_id] = None
    core._refresh_units_live()
    return refused
