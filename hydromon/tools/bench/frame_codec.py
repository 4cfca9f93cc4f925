"""The measurement behind the frame encoding (``contract.Frame``): decode cost per sample of a
frame's payload into a float64 array, for the encodings considered.

``python -m hydromon.tools.bench.frame_codec [N ...]`` prints, per frame size N (default 10
and 100), the best and median of 7 timed passes [us a sample] and the payload bytes a sample,
on one simulated rig (realistic noise, so the numbers carry all their digits):

json-msgspec
    JSON arrays of numbers per channel, decoded by a typed msgspec decoder (unknown fields,
    bools and strings refused in C) and turned into one array with one ``np.array`` call:
    hydromon's encoding (``hydromon.engine.frames.decode_frame`` adds the limit and time checks).
json-orjson
    The same JSON through ``orjson.loads`` (no types checked) and one ``np.array``.
json-base64
    Each channel's float64 bytes, base64 in a JSON string: no number parsing, but nothing a JSON
    tool can plot (Foxglove shows strings).
samples
    N contract samples, one message each, through the monitor's batch decoder
    (``hydromon.engine.samples.sim_samples``): what frames replace.
"""

from __future__ import annotations

import base64
import statistics
import sys
import time

import msgspec
import numpy as np
import orjson

from hydromon.contract import SAMPLE_COLUMNS
from hydromon.engine.frames import block_frames, frame_struct
from hydromon.engine.samples import sample_payload, sim_samples

_B64 = msgspec.json.Decoder(msgspec.defstruct("_B64Frame", [("seq", int), *((c, str) for c in SAMPLE_COLUMNS)])).decode


def _encodings(n: int):
    """``{name: (decode function, payloads of one rig's frame)}`` and the frame's values (n, 6)."""
    from hydromon.store.fleetfile import spread_fleet

    blk = spread_fleet(1, noise="realistic").build().step(n)
    vals = np.column_stack([blk.t, blk.samples[0]])
    json_frame = block_frames(blk, 0, n)[0]
    b64 = orjson.dumps({"seq": 0, **{c: base64.b64encode(vals[:, i].tobytes()).decode()
                                     for i, c in enumerate(SAMPLE_COLUMNS)}})
    singles = [sample_payload(k, float(vals[k, 0]), vals[k, 1:].tolist()) for k in range(n)]

    def json_msgspec():
        f = frame_struct(json_frame)
        return np.array((f.t, f.ug, f.x1, f.x3, f.x4, f.x5)).T

    def json_orjson():
        d = orjson.loads(json_frame)
        return np.array([d[c] for c in SAMPLE_COLUMNS]).T

    def json_base64():
        f, d = _B64(b64), base64.b64decode
        return np.frombuffer(b"".join(d(getattr(f, c)) for c in SAMPLE_COLUMNS), np.float64).reshape(6, -1).T

    def samples():
        return np.array(sim_samples(singles))[:, 1:]

    return {"json-msgspec": (json_msgspec, [json_frame]), "json-orjson": (json_orjson, [json_frame]),
            "json-base64": (json_base64, [b64]), "samples": (samples, singles)}, vals


def measure(n: int, passes: int = 7) -> dict:
    """``{encoding: (best, median) us a sample, bytes a sample}`` for frames of ``n`` samples."""
    encodings, vals = _encodings(n)
    out = {}
    for name, (fn, payloads) in encodings.items():
        if not np.array_equal(fn(), vals):
            raise RuntimeError(f"{name} does not decode to the frame's values")
        calls = 20000 // n + 100
        per = []
        for _ in range(passes):
            t = time.perf_counter()
            for _ in range(calls):
                fn()
            per.append((time.perf_counter() - t) / calls / n * 1e6)
        out[name] = (min(per), statistics.median(per), sum(map(len, payloads)) / n)
    return out


def main(argv: list[str]) -> int:
    import os

    sizes = [int(a) for a in argv] or [10, 100]
    print(f"load average {os.getloadavg()[0]:.2f}")
    for n in sizes:
        for name, (best, med, size) in measure(n).items():
            print(f"N={n:<4} {name:13s} best {best:.3f} us/sample, median {med:.3f}; {size:.0f} B/sample")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
