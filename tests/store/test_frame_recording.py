"""A recording of frames: read by an independent MCAP reader against the JSON Schema its channel
carries, and read by hydromon's readers (replay --direct, evaluate's loader) as the same samples."""

from __future__ import annotations

import io
import json

import jsonschema
import numpy as np
from mcap.reader import make_reader

from hydromon.engine.core import MonitorCore
from hydromon.store.fleetfile import default_fleet
from hydromon.store.mcap_read import read_samples
from hydromon.store.replay import replay_direct
from hydromon.store.simfiles import write_mcap

SPEC = default_fleet(noise="realistic")


def _mcap(frame=None, seconds=4.0) -> bytes:
    buf = io.BytesIO()
    write_mcap(SPEC, seconds, buf, frame=frame)
    return buf.getvalue()


def test_an_independent_reader_validates_every_frame_against_its_channels_schema():
    data = _mcap(frame=7)
    reader = make_reader(io.BytesIO(data))
    frames = 0
    validators = {}
    for schema, channel, message in reader.iter_messages():
        assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
        if channel.topic.endswith("/frame"):
            assert schema.name == "hydromon.Frame"
            v = validators.setdefault(schema.id, jsonschema.Draft202012Validator(json.loads(schema.data)))
            obj = json.loads(message.data)
            v.validate(obj)
            assert message.publish_time == round(obj["t"][0] * 1e9)
            assert message.log_time == round(obj["t"][-1] * 1e9)
            frames += 1
    assert frames == 5 * (4 * 14 + 2)  # 400 samples: 4 blocks of 98 (14 frames each), then 8 samples (7 + 1)
    bad = {"seq": 0, "t": [0.0], "ug": [0.0], "x1": [0.0], "x3": [0.0], "x4": [0.0], "x5": [0.5]}  # x5 > 0.1 m
    assert not next(iter(validators.values())).is_valid(bad)


def test_frames_read_as_the_same_samples_and_replay_to_the_same_health():
    samples, frames = _mcap(), _mcap(frame=10)
    for rig in SPEC.ids[:2]:
        a, b = read_samples(io.BytesIO(samples), rig=rig), read_samples(io.BytesIO(frames), rig=rig)
        assert a[0] == b[0] and np.array_equal(a[1], b[1]) and np.array_equal(a[2], b[2])
    h1, c1 = replay_direct(io.BytesIO(samples), core=MonitorCore())
    h2, c2 = replay_direct(io.BytesIO(frames), core=MonitorCore())
    assert c1.counters.accepted == c2.counters.accepted == 5 * 400
    assert sorted(h1) == sorted(h2) and len(h1) == 5 * 40


def test_every_message_of_a_recording_obeys_its_channels_schema():
    """The golden recording (samples, configs, health, events), read by the independent reader."""
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "recordings" / "table4-realistic.mcap"
    seen = {}
    with open(path, "rb") as f:
        for schema, _, message in make_reader(f).iter_messages():
            v = seen.setdefault(schema.name, jsonschema.Draft202012Validator(json.loads(schema.data)))
            v.validate(json.loads(message.data))
    assert {"hydromon.Sample", "hydromon.Health", "hydromon.Event", "hydromon.RigConfig"} <= set(seen)
