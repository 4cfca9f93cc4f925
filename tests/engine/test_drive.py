"""A rig that publishes its valve drive u is graded without a model of its controller: a digital
PI loop with feed-forward grades as the proportional loop does, live (MonitorCore) and from
files (CSV and MCAP)."""

import io

import numpy as np
import orjson
import pytest

from helpers import by_rig
from hydromon.engine.core import MonitorCore
from hydromon.engine.evaluate import evaluate
from hydromon.store.fleetfile import FleetSpec, RigSpec, true_grade
from hydromon.store.recording import load_recording
from hydromon.store.simfiles import write_csv, write_mcap

PI = "pi:ki=3,kff=0.02"
SECONDS = 20.0


def _fleet(controller: str, publish_u: bool | None = None) -> FleetSpec:
    return FleetSpec(seed=11, rigs=[RigSpec(id=f"g{g}", table4=g, noise="realistic", controller=controller,
                                            publish_u=publish_u) for g in range(1, 6)])


def _graded(spec: FleetSpec, tmp_path) -> dict[str, tuple[str, float]]:
    out = {}
    for rig in spec.ids:
        path = tmp_path / f"{rig}.csv"
        with open(path, "w") as f:
            write_csv(spec, SECONDS, f, rig=rig)
        ev = evaluate(load_recording(path))
        assert ev.recording.drive_samples == (len(ev.recording.samples) if spec.rigs[0].publishes_u else 0)
        out[rig] = (ev.assessment.grade, ev.assessment.params["K_sv"])
    return out


def test_a_pi_loop_with_its_drive_published_grades_as_the_proportional_loop_does(tmp_path):
    p_loop, pi_loop = _graded(_fleet("p"), tmp_path), _graded(_fleet(PI), tmp_path)
    spec = _fleet(PI)
    for r in spec.rigs:
        truth = r.plant().K_sv
        assert pi_loop[r.id][0] == p_loop[r.id][0] == true_grade(r), (r.id, pi_loop[r.id], p_loop[r.id])
        assert abs(pi_loop[r.id][1] / truth - 1) < 0.01, (r.id, pi_loop[r.id][1], truth)


def test_without_its_drive_a_pi_loop_misleads_the_valve_identification(tmp_path):
    # the same loop, u not published: the monitor assumes K_p (ug - K_f x1) and the valve's gain
    # comes out far off (which is why such a rig must publish u)
    spec = FleetSpec(seed=11, rigs=[RigSpec(id="g2", table4=2, noise="realistic", controller=PI, publish_u=False)])
    path = tmp_path / "g2.csv"
    with open(path, "w") as f:
        write_csv(spec, SECONDS, f, rig="g2")
    ev = evaluate(load_recording(path))
    assert ev.recording.drive_samples == 0
    assert abs(ev.assessment.params["K_sv"] / spec.rigs[0].plant().K_sv - 1) > 0.2


def test_the_live_core_and_an_mcap_take_the_drive_as_a_csv_does(tmp_path):
    spec = FleetSpec(seed=3, rigs=[RigSpec(id="g4", table4=4, noise="realistic", controller=PI)])
    buf = io.BytesIO()
    write_mcap(spec, 6.0, buf)
    mcap = tmp_path / "g4.mcap"
    mcap.write_bytes(buf.getvalue())
    from_mcap = evaluate(load_recording(mcap))
    csv = tmp_path / "g4.csv"
    with open(csv, "w") as f:
        write_csv(spec, 6.0, f)
    from_csv = evaluate(load_recording(csv))
    assert from_mcap.recording.drive_samples == 600
    assert from_mcap.assessment.params == from_csv.assessment.params
    # live: the same payloads through the core (each carries u); its last verdict follows its last
    # 10-sample window, evaluate's the last sample: the same estimate a few samples apart
    from hydromon.store.mcap_read import read_recording

    core = MonitorCore()
    health = core.process([(k, p) for k, p, _, _ in read_recording(mcap)])
    last = orjson.loads(by_rig(health)["g4"][-1])
    assert all("u" in orjson.loads(p) for k, p, _, _ in read_recording(mcap) if k.endswith("/sample"))
    np.testing.assert_allclose(last["params"]["K_sv"], from_csv.assessment.params["K_sv"], rtol=1e-5)


@pytest.mark.parametrize("u, reason", [(2e3, "bad-value"), ("1.0", "wrong-type"), (True, "wrong-type"),
                                       ("nan", "non-finite")])
def test_a_bad_drive_value_rejects_the_sample_with_its_reason(u, reason):
    from hydromon.engine.validate import Rejected, parse_sample

    obj = {"seq": 0, "t": 0.0, "ug": 2.0, "x1": 0.0, "x3": 6e6, "x4": 5e6, "x5": 0.0, "u": u}
    with pytest.raises(Rejected) as exc:
        parse_sample(obj)
    assert exc.value.reason == reason
    assert parse_sample({**obj, "u": 1.5})[7] == 1.5 and len(parse_sample({**obj, "u": None})) == 7


def test_a_csv_drive_column_is_read_and_checked_naming_the_line(tmp_path):
    from hydromon.store.csvfile import read_csv

    text = "t,ug,x1,x3,x4,x5,u\n0.0,2,0,6e6,5e6,0,1.5\n0.01,2,0,6e6,5e6,0,\n0.02,2,0,6e6,5e6,0,2e3\n"
    drive: list = []
    with pytest.raises(ValueError, match=r"line 4: u = '2e3' is beyond the contract's limit \|u\| <= 1000"):
        read_csv(io.StringIO(text), drive=drive)
    drive = []
    data = read_csv(io.StringIO(text.rsplit("0.02", 1)[0]), drive=drive)
    assert data.shape == (2, 6) and drive[0] == 1.5 and np.isnan(drive[1])
