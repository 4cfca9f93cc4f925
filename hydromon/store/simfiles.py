"""Simulated rigs written straight into files, as fast as they compute: CSV or MCAP, no bus.

``hydromon sim --to-csv/--to-mcap`` and the benchmarks use these. An MCAP is written as the
recorder would have recorded the fleet from the bus (configs first, then samples; log and
publish time = t).
"""

from __future__ import annotations

import math

import orjson

from hydromon.contract import DEFAULT_NAMESPACE, DRIVE, SAMPLE_COLUMNS, config_key, frame_key, sample_key
from hydromon.engine.frames import block_frames
from hydromon.engine.samples import sample_payload
from hydromon.store.fleetfile import FleetSpec
from plant_sim.live import PlantFleet

__all__ = ["iter_blocks", "select_rig", "file_bytes", "write_csv", "write_mcap", "CSV_BYTES_PER_ROW",
           "MCAP_BYTES_PER_MESSAGE"]


def iter_blocks(fleet: PlantFleet, n_samples: int, block: int = 1000):
    """``fleet.step`` blocks until ``n_samples`` samples per rig are out."""
    if n_samples < 1:
        raise ValueError(f"need at least one sample, got {n_samples!r}")
    done = 0
    while done < n_samples:
        k = min(block, n_samples - done)
        yield fleet.step(k)
        done += k


def _n_samples(duration: float, h: float) -> int:
    if not math.isfinite(duration):
        raise ValueError(f"duration {duration!r} s must be a finite number")
    n = int(round(duration / h)) if duration > 0 else 0
    if n < 1:
        raise ValueError(f"duration {duration!r} s gives no samples at h = {h} s")
    return n


def select_rig(spec: FleetSpec, rig: str | None) -> FleetSpec:
    """The one-rig fleet of rig ``rig`` (None: the fleet must have one rig), with the noise
    seed it has in ``spec``, so its run is the one it has in the whole fleet's run."""
    if rig is None:
        if len(spec.rigs) != 1:
            raise ValueError(f"a CSV holds one rig and the fleet has {len(spec.rigs)} "
                             f"({', '.join(spec.ids[:5])}{', ...' if len(spec.rigs) > 5 else ''}); choose one (--rig ID)")
        rig = spec.ids[0]
    if rig not in spec.ids:
        raise ValueError(f"no rig {rig!r} in the fleet")
    return FleetSpec(config=spec.config, seed=spec.seed,
                     rigs=[r.model_copy(update={"seed": s}) for r, s in zip(spec.rigs, spec.seeds()) if r.id == rig])


CSV_BYTES_PER_ROW = 90
"""A lower bound of a CSV row's size (measured: 104 bytes; each float written exactly)."""


MCAP_BYTES_PER_MESSAGE = 55
"""A lower bound of a sample message's share of an MCAP file (measured: 63 bytes, compressed)."""


def file_bytes(kind: str, duration: float, h: float, n_rigs: int = 1) -> float:
    """What ``write_csv`` (``kind`` "csv", one rig) or ``write_mcap`` ("mcap") will write for
    ``duration`` [s] at step ``h`` [s], at least [bytes]: checked against the free disk first."""
    per = {"csv": CSV_BYTES_PER_ROW, "mcap": MCAP_BYTES_PER_MESSAGE}[kind]
    return float(_n_samples(duration, h)) * n_rigs * per


def write_csv(spec: FleetSpec, duration: float, stream, rig: str | None = None, on_block=None) -> int:
    """Write one rig's run of ``duration`` [s] as CSV ``t,ug,x1,x3,x4,x5`` (SI) to a text stream,
    and ``u`` (the valve drive [V]) when the rig publishes it.

    ``rig`` picks a rig of the fleet by id (needed if it has several). ``on_block(done, total)``
    (samples) is called after each block. Returns the row count.
    """
    one = select_rig(spec, rig)
    n = _n_samples(duration, one.config.h)  # before the first byte
    fleet = one.build()
    with_u = one.rigs[0].publishes_u
    stream.write(",".join((*SAMPLE_COLUMNS, DRIVE) if with_u else SAMPLE_COLUMNS) + "\n")
    rows = 0
    for blk in iter_blocks(fleet, n):
        us = blk.u[0].tolist() if with_u else None
        for j, (t, row) in enumerate(zip(blk.t.tolist(), blk.samples[0].tolist())):
            stream.write(",".join(map(repr, [t, *row, us[j]] if with_u else [t, *row])) + "\n")
            rows += 1
        if on_block is not None:
            on_block(rows, n)
    return rows


def write_mcap(spec: FleetSpec, duration: float, stream, namespace: str = DEFAULT_NAMESPACE,
               on_block=None, frame: int | None = None) -> int:
    """Write the fleet's run of ``duration`` [s] to an MCAP stream as the recorder would have
    recorded it from the bus (configs first, then samples; log and publish time = t). With
    ``frame`` N, frames of N samples (``hydromon sim --frame N``; the last one of the run may be
    shorter), logged at their last sample's t and published at their first's.

    ``on_block(done, total)`` (samples per rig) is called after each block. Returns the number
    of messages written.
    """
    from hydromon.store.mcap_write import RecordingWriter

    n = _n_samples(duration, spec.config.h)  # before the first byte
    fleet = spec.build()
    skeys = [sample_key(i, namespace) for i in spec.ids]
    with_u = [r.publishes_u for r in spec.rigs]
    with RecordingWriter(stream) as writer:
        for i, key in enumerate(config_key(i, namespace) for i in spec.ids):
            writer.write(key, orjson.dumps(fleet.configs[i].model_dump(mode="json")), 0, 0)
        done = 0
        if frame is not None:
            fkeys = [frame_key(i, namespace) for i in spec.ids]
            drives = frozenset(r for r, on in enumerate(with_u) if on)
            for blk in iter_blocks(fleet, n, block=frame * max(1, 100 // frame)):
                ts = blk.t.tolist()
                for j0 in range(0, len(ts), frame):
                    j1 = min(j0 + frame, len(ts))
                    pub_ns, log_ns = int(round(ts[j0] * 1e9)), int(round(ts[j1 - 1] * 1e9))
                    for key, payload in zip(fkeys, block_frames(blk, j0, j1, drives)):
                        writer.write(key, payload, log_ns, pub_ns)
                done += len(ts)
                if on_block is not None:
                    on_block(done, n)
            return writer.message_count
        for blk in iter_blocks(fleet, n, block=100):
            rows, us = blk.samples.tolist(), blk.u.tolist()
            for j, (seq, t) in enumerate(zip(blk.seq.tolist(), blk.t.tolist())):
                t_ns = int(round(t * 1e9))
                for r, key in enumerate(skeys):
                    writer.write(key, sample_payload(seq, t, rows[r][j], us[r][j] if with_u[r] else None), t_ns, t_ns)
            done += len(blk.t)
            if on_block is not None:
                on_block(done, n)
        return writer.message_count
