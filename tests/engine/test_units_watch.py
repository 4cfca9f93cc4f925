"""The live monitor says ``bad-input`` for a rig whose readings its config cannot hold
(``hydromon.engine.units_watch``): a spool in 0.01 mm or pressures with their sign turned fit the
model with the units in the parameters, and were graded ``health``, status ``ok``."""

from __future__ import annotations

import numpy as np
import orjson
import pytest

from hydromon.contract import RigConfig
from hydromon.engine.core import MonitorCore
from hydromon.engine.frames import frame_payload
from hydromon.engine.samples import sample_payload
from monitor.readings import GLITCH_SAMPLES, sample_limits
from plant_sim.degradation import degrade
from plant_sim.noise import noise_model
from plant_sim.profiles import parse_profile
from plant_sim.simulate import simulate

NS = "hydro"


@pytest.fixture(scope="module")
def healthy():
    return simulate(parse_profile("paper-var"), 10.0, params=degrade(0.05), noise=noise_model("realistic"), seed=1)


def _messages(run, samples, config=None, frame=None, rig="a"):
    msgs = [] if config is None else [(f"{NS}/rig/{rig}/config", orjson.dumps(config.model_dump(mode="json")))]
    if frame is None:
        return msgs + [(f"{NS}/rig/{rig}/sample", sample_payload(k, float(run.t[k]), samples[k].tolist()))
                       for k in range(len(samples))]
    return msgs + [(f"{NS}/rig/{rig}/frame", frame_payload(k, run.t[k:k + frame].tolist(),
                                                           samples[k:k + frame].T.tolist()))
                   for k in range(0, len(samples), frame)]


def _run(msgs, batch=None):
    warnings = []
    core = MonitorCore(NS, on_warning=lambda rig, msg: warnings.append((rig, msg)))
    out = []
    step = batch or len(msgs)
    for j in range(0, len(msgs), step):
        out += core.process(msgs[j:j + step])
    health = [p for k, p in out if k.endswith("/health")]
    return health, [orjson.loads(p)["status"] for p in health], warnings


def _scaled(run, columns, factor):
    s = run.samples.copy()
    s[:, columns] *= factor
    return s


@pytest.mark.parametrize("columns, factor, said", [
    ([4], 100.0, "x5 reaches"), ([2, 3], -1.0, "falls to -"), ([3], -1.0, "x4 falls to -")])
def test_a_rig_whose_readings_its_config_cannot_hold_says_bad_input_and_is_warned_of_once(healthy, columns, factor,
                                                                                          said):
    _, status, warnings = _run(_messages(healthy, _scaled(healthy, columns, factor)), batch=50)
    assert status[0] in ("bad-input", "converging") and set(status[1:]) == {"bad-input"}, status
    assert len(warnings) == 1 and warnings[0][0] == "a" and said in warnings[0][1], warnings
    assert "its health says bad-input" in warnings[0][1]


def test_the_same_record_in_si_and_one_with_a_lone_glitch_are_trusted(healthy):
    _, status, warnings = _run(_messages(healthy, healthy.samples), batch=50)
    assert "bad-input" not in status and status[-1] == "ok" and warnings == []
    s = healthy.samples.copy()
    s[500, 3] = -16e6  # one sample far below vacuum: the outlier gate's, not a unit slip
    for k in range(600, 1000, 50):  # and glitches the gate mends, again and again: a pair of x4, one of x5
        s[k:k + GLITCH_SAMPLES, 3] = -16e6
        s[k + 25, 4] = 0.05  # (within the contract's |x5| <= 0.1 m, which rejects the sample)
    _, status, warnings = _run(_messages(healthy, s), batch=50)
    assert "bad-input" not in status and warnings == []


def test_the_bounds_are_the_rig_config_s():
    """A spool that travels 30 mm on a valve whose config says so is in range; against the default
    1 mm span it is not."""
    run = simulate(parse_profile("paper-var"), 5.0, params=degrade(0.05), seed=2)
    s = _scaled(run, [4], 100.0)
    _, status, _ = _run(_messages(run, s, RigConfig(x5_span=0.03)), batch=50)
    assert "bad-input" not in status
    _, status, _ = _run(_messages(run, s, RigConfig()), batch=50)
    assert set(status[1:]) == {"bad-input"}
    # both on one monitor, their samples interleaved: each is held against its own config
    mixed = [m for pair in zip(_messages(run, s, RigConfig(x5_span=0.03), rig="wide"),
                               _messages(run, s, RigConfig(), rig="narrow")) for m in pair]
    core = MonitorCore(NS)
    out = core.process(mixed)
    status = {rig: [orjson.loads(p)["status"] for k, p in out if k == f"{NS}/rig/{rig}/health"] for rig in ("wide",
                                                                                                         "narrow")}
    assert "bad-input" not in status["wide"] and set(status["narrow"][1:]) == {"bad-input"}, status


def test_the_health_does_not_depend_on_how_the_messages_were_batched_or_framed(healthy):
    s = healthy.samples.copy()
    s[:, 4] *= 30  # beyond 10 mm only where the spool opens more than 0.33 mm: some windows only
    msgs = _messages(healthy, s)
    one, status, _ = _run(msgs)
    assert 0 < status.count("bad-input") < len(status)
    for batch in (1, 7, 64):
        assert _run(msgs, batch)[0] == one, batch
    assert _run(_messages(healthy, s, frame=10), batch=3)[0] == one


def test_a_restarted_rig_is_counted_afresh(healthy):
    bad = _messages(healthy, _scaled(healthy, [2, 3], -1.0))[:300]
    good = _messages(healthy, healthy.samples)
    _, status, warnings = _run(bad + good, batch=50)  # seq goes back to 0: the rig restarted
    assert status[:25].count("bad-input") >= 25 and status[-1] == "ok" and len(warnings) >= 1
    assert "bad-input" not in status[-50:]


def test_an_empty_batch_of_a_known_rig_changes_nothing(healthy):
    core = MonitorCore(NS)
    core.process(_messages(healthy, _scaled(healthy, [4], 100.0))[:100])
    before = int(core._units[core.rigs["a"].row])
    assert core.process([]) == [] and int(core._units[core.rigs["a"].row]) == before > GLITCH_SAMPLES
    np.testing.assert_array_equal(core._limits[core.rigs["a"].row], sample_limits(RigConfig()))


def test_the_monitor_s_exit_summary_names_the_rigs_whose_readings_broke_their_bounds(healthy):
    from hydromon.cli.commands.monitor import units_line

    core = MonitorCore(NS)
    assert units_line(core) is None
    out = core.process(_messages(healthy, _scaled(healthy, [2, 3], -1.0), rig="neg")[:200]
                       + _messages(healthy, healthy.samples, rig="fine")[:200])
    said = [orjson.loads(p)["status"] for k, p in out if k == f"{NS}/rig/neg/health"]
    # every sample beyond: each evaluation that holds more than GLITCH_SAMPLES samples found them
    assert list(core.units_flagged()) == ["neg"] and core.units_flagged()["neg"] == said.count("bad-input") >= 19
    assert units_line(core).endswith(f": neg in {core.units_flagged()['neg']} evaluation(s)")


def test_a_rig_restored_from_a_checkpoint_keeps_its_slip_and_its_warning(healthy):
    """As a monitor that ran on through the same gap: its health byte for byte, and no second
    warning."""
    from hydromon.engine.checkpoint import decode, encode, restore, snapshot
    from hydromon.engine.units_watch import UNITS_WINDOWS

    s = healthy.samples.copy()
    s[:, 4] *= 30  # beyond 10 mm only where the spool opens more than 0.33 mm: some windows only
    msgs = _messages(healthy, s)
    cut, back = 600, 700
    through = MonitorCore(NS)
    through.process(msgs[:cut])
    expected = through.process(msgs[back:])
    first = MonitorCore(NS)
    first.process(msgs[:cut])
    assert first.units_flagged()["a"] >= UNITS_WINDOWS
    warnings = []
    restarted = MonitorCore(NS, on_warning=lambda rig, msg: warnings.append((rig, msg)))
    assert restore(restarted, decode(encode(snapshot(first)))) == []
    got = restarted.process(msgs[back:])
    assert got == expected and warnings == []
    status = [orjson.loads(p)["status"] for k, p in got if k.endswith("/health")]
    assert set(status) == {"bad-input"}, status
    forgot = decode(encode(snapshot(first)))  # as restored without the watch's counts
    forgot.rows[:, -3:] = 0
    fresh = MonitorCore(NS)
    restore(fresh, forgot)
    status = [orjson.loads(p)["status"] for k, p in fresh.process(msgs[back:]) if k.endswith("/health")]
    assert "ok" in status, status  # the slip forgotten, its readings trusted between the spool's wide openings
