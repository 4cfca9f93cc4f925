"""A monitor restored from its checkpoint resumes as if it had run on and lost the samples it
missed: the same health, byte for byte; a checkpoint it cannot use is refused whole, never
half-loaded."""

import io

import numpy as np
import orjson
import pytest

from helpers import by_rig, fleet_messages
from hydromon.contract import Health, RigConfig
from hydromon.engine.checkpoint import CheckpointRefused, decode, encode, restore, snapshot
from hydromon.engine.core import MonitorCore
from hydromon.store.fleetfile import default_fleet
from monitor.ident_options import IdentOptions


@pytest.fixture(scope="module")
def messages():
    return fleet_messages(default_fleet(noise="realistic"), 14.0)


def _split(msgs, at_s: float, back_s: float):
    """(before, after): the configs and samples before ``at_s`` [s], and the samples from
    ``back_s`` [s] on (the ones between are lost while the monitor is down)."""
    before, after = [], []
    for key, payload in msgs:
        if key.endswith("/config"):
            before.append((key, payload))
            continue
        t = orjson.loads(payload)["t"]
        if t < at_s:
            before.append((key, payload))
        elif t >= back_s:
            after.append((key, payload))
    return before, after


def test_a_restored_monitor_gives_the_health_of_one_that_ran_on_through_the_same_gap(messages):
    before, after = _split(messages, 8.0, 9.5)
    through = MonitorCore(node="m", epoch=1)
    through.process(before)
    expected = through.process(after)

    first = MonitorCore(node="m", epoch=1)
    first.process(before)
    data = encode(snapshot(first))
    restarted = MonitorCore(node="m", epoch=1)
    assert restore(restarted, decode(data)) == []
    got = restarted.process(after)
    assert got == expected  # byte for byte, the configs included: no rig resent its config
    # and it kept what it had learnt: every rig's first health after the gap has its grade of before
    last_before = {rig: Health.model_validate_json(p) for rig, p in first.latest.items()}
    for rig, payloads in by_rig(got).items():
        h = Health.model_validate_json(payloads[0])
        assert h.grade == last_before[rig].grade != "unknown"
        assert h.status == "stale"  # the filters restart after the gap
    assert restarted.counters.gaps == len(last_before)


def test_a_rig_that_sent_its_config_once_is_graded_on_it_after_a_restart(messages):
    """The config comes once, before the first sample: the checkpoint is the only copy left."""
    before, after = _split(messages, 6.0, 6.5)
    first = MonitorCore()
    first.process(before)
    restarted = MonitorCore()
    restore(restarted, decode(encode(snapshot(first))))
    assert restarted.configs == first.configs and restarted.configs
    restarted.process(after)
    for rig_id, rig in restarted.rigs.items():
        assert rig.config == first.configs[rig_id]


def test_a_checkpoint_of_other_estimator_settings_is_refused_and_the_core_left_untouched(messages):
    before, _ = _split(messages, 4.0, 4.0)
    first = MonitorCore()
    first.process(before)
    ckpt = decode(encode(snapshot(first)))
    other = MonitorCore(options=IdentOptions(a_force=0.999))
    with pytest.raises(CheckpointRefused, match="other estimator settings"):
        restore(other, ckpt)
    assert not other.rigs and not other.configs
    with pytest.raises(CheckpointRefused, match="eval_every"):
        restore(MonitorCore(eval_every=5), ckpt)


def test_another_layout_or_format_or_damaged_bytes_are_refused(messages):
    first = MonitorCore()
    first.process(_split(messages, 3.0, 3.0)[0])
    data = encode(snapshot(first))
    for field, value, words in (("layout", "0123456789abcdef", "state layout"), ("format", 99, "format 99")):
        with np.load(io.BytesIO(data)) as z:
            arrays = dict(z)
        meta = orjson.loads(arrays["meta"].tobytes())
        meta[field] = value
        arrays["meta"] = np.frombuffer(orjson.dumps(meta), dtype=np.uint8)
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        with pytest.raises(CheckpointRefused, match=words):
            decode(buf.getvalue())
    for bad in (b"", data[: len(data) // 2], b"PK\x03\x04" + bytes(100)):
        with pytest.raises(CheckpointRefused, match="not a readable checkpoint"):
            decode(bad)


def test_a_format_1_checkpoint_without_the_units_watch_s_counts_is_read_as_fresh_counts(messages):
    before, after = _split(messages, 6.0, 7.0)
    first = MonitorCore()
    first.process(before)
    with np.load(io.BytesIO(encode(snapshot(first)))) as z:
        arrays = dict(z)
    meta = orjson.loads(arrays["meta"].tobytes())
    meta["format"] = 1
    arrays["meta"] = np.frombuffer(orjson.dumps(meta), dtype=np.uint8)
    arrays["rows"] = arrays["rows"][:, :8]  # format 1 holds the sequence state only
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    old = decode(buf.getvalue())
    assert old.meta["format"] == 2 and old.rows.shape == (len(old.rigs), 11) and not old.rows[:, 8:].any()
    arrays["rows"] = arrays["rows"][:, :7]
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    with pytest.raises(CheckpointRefused, match="disagree"):
        decode(buf.getvalue())
    restarted, through = MonitorCore(), MonitorCore()
    assert restore(restarted, old) == []
    through.process(before)
    assert restarted.process(after) == through.process(after)  # in SI, nothing was counted to lose


def test_a_rig_whose_saved_constants_its_config_no_longer_gives_is_refused_alone(messages):
    first = MonitorCore()
    first.process(_split(messages, 3.0, 3.0)[0])
    ckpt = decode(encode(snapshot(first)))
    victim = ckpt.meta["rigs"][1]
    ckpt.consts[1, 0] *= 1.5  # as if the constants were derived otherwise when it was saved
    restarted = MonitorCore()
    refused = restore(restarted, ckpt)
    assert [r for r, _ in refused] == [victim]
    assert victim not in restarted.rigs and len(restarted.rigs) == len(ckpt.meta["rigs"]) - 1
    assert restarted.configs[victim] == RigConfig.model_validate(ckpt.meta["configs"][victim])
