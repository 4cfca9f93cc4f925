"""Simulator node: pacing, fleet files, CLI flags, file modes and a loopback run on zenoh."""

from __future__ import annotations

import io
import json
import threading
import time

import numpy as np
import pytest

from hydromon.store import quantities
import zenoh
from hypothesis import given
from hypothesis import strategies as st

from hydromon.bus import sim as simnode
from hydromon.bus.session import listening_session, loads, make_config, open_session
from hydromon.bus.sim import run_sim, sample_deadline, wait_time
from hydromon.cli.commands.sim import build_fleet
from hydromon.cli.main import build_parser
from hydromon.contract import RigConfig, Sample
from hydromon.store import simfiles
from hydromon.store.fleetfile import (
    EFFECT_FIELDS,
    FleetSpec,
    RigSpec,
    default_fleet,
    load_fleet,
    parse_effect,
    spread_fleet,
)
from plant_sim.degradation import degrade, table4_group
from plant_sim.noise import noise_model
from plant_sim.params import EFFECT_NAMES, Effects
from plant_sim.profiles import parse_profile
from plant_sim.simulate import simulate, simulate_fleet

# -- pacing -----------------------------------------------------------------------------------


@given(t0=st.floats(0, 1e6), k=st.integers(0, 10**9), rate=st.floats(0.01, 1000))
def test_deadline_is_computed_from_k_alone(t0, k, rate):
    h = 0.01
    assert sample_deadline(t0, k, h, rate) == t0 + k * h / rate


def test_deadlines_do_not_drift_where_summed_sleeps_would():
    h, t0, k = 0.01, 1000.0, 3_600_000  # ten hours at 100 Hz
    summed = t0
    for _ in range(k):
        summed += h
    exact = sample_deadline(t0, k, h, 1.0)
    assert abs(exact - (t0 + 36_000.0)) < 1e-9
    assert abs(summed - (t0 + 36_000.0)) > 1e-7  # what accumulating h would have done


def test_a_late_sample_does_not_move_the_next_deadlines():
    h, t0 = 0.01, 50.0
    assert wait_time(t0 + 0.5, t0, 10, h, 1.0) == 0.0  # sample 10 is 0.4 s late: send at once
    # and sample 60 is still due at t0 + 0.6, not 0.1 s after the late one
    assert wait_time(t0 + 0.5, t0, 60, h, 1.0) == pytest.approx(0.1, abs=1e-12)
    assert wait_time(t0 + 0.5, t0, 60, h, 2.0) == 0.0  # at 2x, 60 was due at t0 + 0.3
    assert wait_time(t0 + 0.5, t0, 10**6, h, 0.0) == 0.0  # rate 0: as fast as possible
    with pytest.raises(ValueError, match="rate"):
        sample_deadline(t0, 1, h, -1.0)


# -- fleet files ------------------------------------------------------------------------------

TOML = """
seed = 5
[config]
F_L = 3000.0
[[rigs]]
id = "press-1"
severity = 0.35
profile = "paper-id"
noise = "realistic"
effects = { stribeck_friction = 40.0, sensor_delay = 2 }
sensor_delay_loop = true
[[rigs]]
id = "press_2"
table4 = 3
params = { f_c = 30.0 }
seed = 99
"""


def test_toml_and_json_fleet_files(tmp_path):
    (tmp_path / "f.toml").write_text(TOML)
    spec = load_fleet(tmp_path / "f.toml")
    assert spec.ids == ["press-1", "press_2"]
    assert spec.config.F_L == 3000.0
    r1, r2 = spec.rigs
    assert r1.plant() == degrade(0.35)
    assert r1.effects_model() == Effects(stribeck_F_s=40.0, sensor_delay=2, sensor_delay_in_loop=True)
    assert r2.plant() == table4_group(3).model_copy(update={"f_c": 30.0})
    assert spec.seeds()[1] == 99 and spec.seeds()[0] != spec.seeds()[1]
    (tmp_path / "f.json").write_text(json.dumps(spec.model_dump(mode="json")))
    assert load_fleet(tmp_path / "f.json") == spec


def test_every_effect_name_maps_to_its_field():
    assert set(EFFECT_FIELDS) == set(EFFECT_NAMES)
    for name, (field, _unit) in EFFECT_FIELDS.items():
        mag = 0.5 * quantities.EFFECTS[name].hi  # a sensible magnitude of each (a valve's stop at 0.5 mm)
        eff = RigSpec(id="r", effects={name: mag}).effects_model()
        assert getattr(eff, field) == mag
        assert eff.model_copy(update={field: Effects.model_fields[field].default}) == Effects()


@pytest.mark.parametrize("rig, match", [
    (dict(id="bad id!"), "bad id!"),
    (dict(id="x" * 65), "1-64"),
    (dict(id="r", effects={"wobble": 1.0}), "wobble"),
    (dict(id="r", effects=["stribeck_friction"]), "NAME=MAGNITUDE"),
    (dict(id="r", effects=["load_offset=lots"]), "lots"),
    (dict(id="r", severity=1.5), "1.5"),
    (dict(id="r", severity=-0.1), "-0.1"),
    (dict(id="r", table4=6), "table4 group 6"),
    (dict(id="r", table4=1, severity=0.2), "not both"),
    (dict(id="r", params={"mass": 3.0}), "mass"),
    (dict(id="r", params={"m": -3.0}), "params m -3 kg is outside 0..100000 kg"),
    (dict(id="r", effects={"sensor_delay": 1.5}), "sensor_delay 1.5"),
    (dict(id="r", effects={"entrained_air": 2.0}), "entrained_air 2 is outside 0..0.2"),
    (dict(id="r", effects={"valve_dead_band": 2.5}), "valve_dead_band 2.5 m is outside 0..1 mm: give a unit, e.g. 2.5um"),
    (dict(id="r", params={"K_sv": "0.25"}), "K_sv 0.25 m/V is outside 0..10 mm/V"),
    (dict(id="r", config={"p_s": 120}), "config p_s 120 Pa is outside 0.1..100 MPa"),
    (dict(id="r", base={"f_c": "5V"}), "V is not a unit of N"),
    (dict(id="r", profile="zigzag"), "zigzag"),
    (dict(id="r", noise="loud"), "loud"),
])
def test_bad_rig_specs_name_the_bad_value(rig, match):
    with pytest.raises(ValueError, match=match):
        RigSpec(**rig)


def test_bad_fleet_files(tmp_path):
    p = tmp_path / "dup.toml"
    p.write_text('[[rigs]]\nid = "a"\n[[rigs]]\nid = "a"\n')
    with pytest.raises(ValueError, match="'a' appears twice"):
        load_fleet(p)
    p.write_text('[[rigs]]\nid = "a"\nwobble = 1\n')
    with pytest.raises(ValueError, match="wobble"):
        load_fleet(p)
    p.write_text("rigs = [")
    with pytest.raises(ValueError, match="dup.toml"):
        load_fleet(p)
    (tmp_path / "e.json").write_text('{"rigs": []}')
    with pytest.raises(ValueError, match="rigs"):
        load_fleet(tmp_path / "e.json")


def test_parse_effect():
    assert parse_effect("valve_dead_band=1e-5") == ("valve_dead_band", 1e-5)
    with pytest.raises(ValueError, match="unknown effect 'x'"):
        parse_effect("x=1")


def test_default_and_spread_fleets():
    d = default_fleet()
    assert d.ids == [f"table4-g{g}" for g in range(1, 6)]
    assert [r.plant() for r in d.rigs] == [table4_group(g) for g in range(1, 6)]
    assert {r.profile for r in d.rigs} == {"paper-var"}
    s = spread_fleet(5)
    assert [r.severity for r in s.rigs] == [0.0, 0.25, 0.5, 0.75, 1.0]
    r1, r2 = spread_fleet(50, seed=3), spread_fleet(50, seed=3)
    assert r1 == r2 and len({r.severity for r in r1.rigs}) == 50
    assert spread_fleet(50, seed=4) != r1


def _args(*argv):
    return build_parser().parse_args(["sim", *argv])


def test_cli_flags_build_the_fleet(tmp_path):
    assert build_fleet(_args()) == default_fleet()
    one = build_fleet(_args("--severity", "0.7", "--noise", "stress", "--effect", "load_offset=200",
                            "--effect", "sensor_delay=2", "--sensor-delay-loop", "--profile", "steps"))
    (r,) = one.rigs
    assert r.plant() == degrade(0.7) and r.noise == "stress" and r.profile == "steps"
    assert r.effects_model() == Effects(load_offset=200.0, sensor_delay=2, sensor_delay_in_loop=True)
    many = build_fleet(_args("--rigs", "7", "--seed", "1"))
    assert len(many.rigs) == 7 and many.seed == 1 and many == build_fleet(_args("--rigs", "7", "--seed", "1"))
    (tmp_path / "f.toml").write_text(TOML)
    f = build_fleet(_args("--fleet", str(tmp_path / "f.toml"), "--severity", "0.5"))
    assert [r.plant() for r in f.rigs] == [degrade(0.5), degrade(0.5, f_c=30.0)]
    with pytest.raises(ValueError, match="--fleet or --rigs"):
        build_fleet(_args("--fleet", "x.toml", "--rigs", "2"))
    with pytest.raises(ValueError, match="nope"):
        build_fleet(_args("--effect", "nope=1"))


# -- file modes -------------------------------------------------------------------------------


def test_fleet_spec_builds_the_plants_it_describes():
    spec = FleetSpec(seed=2, rigs=[RigSpec(id="a", severity=0.3, noise="realistic"),
                                   RigSpec(id="b", table4=4, profile="chirp", effects={"stribeck_friction": 20})])
    got = spec.build().step(100).samples
    ref = simulate_fleet(spec.config, [degrade(0.3), table4_group(4)],
                         [parse_profile("paper-var"), parse_profile("chirp")], 1.0,
                         [Effects(), Effects(stribeck_F_s=20.0)], None, spec.seeds())
    np.testing.assert_array_equal(got[1], ref[1].samples)  # noise-free rig
    noisy = simulate(parse_profile("paper-var"), 1.0, degrade(0.3), spec.config, None,
                     noise_model("realistic"), spec.seeds()[0])
    np.testing.assert_array_equal(got[0], noisy.samples)


def test_write_csv_is_one_rigs_run():
    spec = spread_fleet(3, seed=8).with_overrides(noise="realistic")
    buf = io.StringIO()
    assert simfiles.write_csv(spec, 0.5, buf, rig="rig-0001") == 50
    lines = buf.getvalue().splitlines()
    assert lines[0] == "t,ug,x1,x3,x4,x5"
    data = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
    r = spec.rigs[1]
    ref = simulate(parse_profile(r.profile), 0.5, r.plant(), spec.config, None, noise_model("realistic"),
                   spec.seeds()[1])
    np.testing.assert_array_equal(data, np.column_stack([ref.t, ref.samples]))  # repr round-trips
    with pytest.raises(ValueError, match="fleet has 3"):
        simfiles.write_csv(spec, 0.5, io.StringIO())
    with pytest.raises(ValueError, match="no rig 'zz'"):
        simfiles.write_csv(spec, 0.5, io.StringIO(), rig="zz")


def test_write_mcap_reads_back_as_samples_and_config():
    from hydromon.store import mcap_read
    spec = FleetSpec(config=RigConfig(F_L=3500.0), rigs=[RigSpec(id="a", severity=0.2), RigSpec(id="b", table4=1)])
    buf = io.BytesIO()
    assert simfiles.write_mcap(spec, 0.3, buf) == 2 + 2 * 30
    rig, data, seq = mcap_read.read_samples(io.BytesIO(buf.getvalue()), rig="b")
    ref = simulate(parse_profile("paper-var"), 0.3, table4_group(1), spec.config, seed=spec.seeds()[1])
    np.testing.assert_array_equal(data, np.column_stack([ref.t, ref.samples]))
    np.testing.assert_array_equal(seq, np.arange(30))
    assert mcap_read.read_rig_config(io.BytesIO(buf.getvalue()), "a") == spec.config


# -- on the bus (loopback) --------------------------------------------------------------------


def _drain(sub, want: int, timeout: float = 20.0) -> list:
    got, end = [], time.monotonic() + timeout
    while len(got) < want and time.monotonic() < end:
        s = sub.try_recv()
        if s is None:
            time.sleep(0.002)
        else:
            got.append(s)
    return got


def _handshake(pub_session, sub_session, timeout: float = 10.0) -> None:
    """Return once data from ``pub_session`` reaches ``sub_session``.

    Declarations travel asynchronously (``matching_status`` may say True before the route
    exists), so: declare the test's subscribers first, then this probe subscriber on the same
    session, and put until a probe arrives; the earlier declarations arrived before it.
    """
    probe = sub_session.declare_subscriber("probe/handshake", zenoh.handlers.FifoChannel(100))
    end = time.monotonic() + timeout
    try:
        while time.monotonic() < end:
            pub_session.put("probe/handshake", b"1")
            time.sleep(0.01)
            if probe.try_recv() is not None:
                return
        raise AssertionError("the subscriber session never heard the publisher")
    finally:
        probe.undeclare()


def _check_stream(samples, spec: FleetSpec, n: int) -> None:
    by_rig: dict[str, list] = {i: [] for i in spec.ids}
    configs = {}
    for s in samples:
        key = str(s.key_expr)
        assert str(s.encoding) == str(zenoh.Encoding.APPLICATION_JSON)
        rig, leaf = key.split("/")[2], key.split("/")[3]
        if leaf == "sample":
            by_rig[rig].append(Sample.model_validate_json(s.payload.to_bytes()))
        else:
            configs[rig] = RigConfig.model_validate(loads(s.payload))
    assert configs == {i: spec.config for i in spec.ids}
    ref = spec.build().step(n)
    for r, rig in enumerate(spec.ids):
        got = by_rig[rig]
        assert [p.seq for p in got] == list(range(n)), rig  # all there, in order
        np.testing.assert_array_equal([[p.ug, p.x1, p.x3, p.x4, p.x5] for p in got], ref.samples[r])
        np.testing.assert_array_equal([p.t for p in got], ref.t)


@pytest.mark.network
@pytest.mark.timeout(60)
def test_loopback_two_rigs_every_sample_in_order():
    spec = FleetSpec(config=RigConfig(F_L=4200.0), seed=3,
                     rigs=[RigSpec(id="r-1", severity=0.1, noise="realistic"), RigSpec(id="r-2", table4=5)])
    with listening_session() as (pub_s, ep), open_session("peer", connect=[ep]) as sub_s:
        sub = sub_s.declare_subscriber("hydro/rig/**", zenoh.handlers.FifoChannel(1000))
        _handshake(pub_s, sub_s)
        stats: list = []
        th = threading.Thread(target=lambda: stats.append(run_sim(pub_s, spec, rate=0, duration=0.5, block=7)))
        th.start()
        th.join(30)
        assert not th.is_alive()
        got = _drain(sub, 2 + 2 * 50)
        time.sleep(0.1)
        assert sub.try_recv() is None  # nothing more than expected
    assert stats[0].samples == 50 and stats[0].published == 100 and stats[0].configs_published == 2
    _check_stream(got, spec, 50)


@pytest.mark.network
@pytest.mark.timeout(60)
def test_through_a_router_with_config_queries_and_changes():
    # a router in this process (what ``hydromon router`` runs), on a free port
    with listening_session("router") as (_router, ep):
        spec = default_fleet()
        with zenoh.open(make_config("client", connect=[ep])) as sim_s, \
                open_session("client", connect=[ep]) as sub_s:
            sub = sub_s.declare_subscriber("hydro/rig/*/config", zenoh.handlers.FifoChannel(100))
            _handshake(sim_s, sub_s)
            node = simnode.SimNode(sim_s, spec.ids, spec.build(), rate=20.0, block=5)
            stop, stats = threading.Event(), []
            th = threading.Thread(target=lambda: stats.append(node.run(stop_event=stop)))
            th.start()
            try:
                first = _drain(sub, 5)
                assert sorted(str(s.key_expr) for s in first) == [f"hydro/rig/{i}/config" for i in spec.ids]
                # a late joiner asks for the current configs
                replies = [r.ok for r in sub_s.get("hydro/rig/*/config", timeout=5.0) if r.ok is not None]
                assert sorted(str(r.key_expr) for r in replies) == sorted(str(s.key_expr) for s in first)
                new = RigConfig(p_s=10e6)
                node.change_rig("table4-g3", config=new)
                (again,) = _drain(sub, 1)
                assert str(again.key_expr) == "hydro/rig/table4-g3/config"
                assert RigConfig.model_validate_json(again.payload.to_bytes()) == new
            finally:
                stop.set()
                th.join(20)
            assert not th.is_alive() and stats[0].configs_published == 6
            with pytest.raises(ValueError, match="no rig 'nope'"):
                node.change_rig("nope", config=new)


def test_node_arguments_are_checked():
    spec = default_fleet()
    with pytest.raises(ValueError, match="5 rigs"):
        simnode.SimNode(None, ["a"], spec.build())
    with pytest.raises(ValueError, match="rate"):
        simnode.SimNode(None, spec.ids, spec.build(), rate=-1)
    with pytest.raises(ValueError, match="namespace"):
        simnode.SimNode(None, spec.ids, spec.build(), namespace="a b")


def test_cli_sim_to_csv_and_errors(tmp_path, capsys):
    from hydromon.cli.main import main

    out = tmp_path / "run.csv"
    assert main(["sim", "--severity", "0.4", "--duration", "0.2", "--to-csv", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert lines[0] == "t,ug,x1,x3,x4,x5" and len(lines) == 21
    assert main(["sim", "--to-csv", str(out)]) == 2
    assert "--duration" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text('[[rigs]]\nid = "a"\nseverity = 3\n')
    assert main(["sim", "--fleet", str(bad), "--duration", "1", "--to-csv", str(out)]) == 2
    assert "rigs.0.severity: severity 3.0 must lie in [0, 1]" in capsys.readouterr().err


def test_file_size_estimates_are_lower_bounds_of_what_is_written():
    # the disk check refuses on these estimates: one above the truth would refuse a run that fits
    spec = spread_fleet(3, seed=2).with_overrides(noise="realistic")
    csv, mcap = io.StringIO(), io.BytesIO()
    simfiles.write_csv(spec, 2.0, csv, rig="rig-0000")
    simfiles.write_mcap(spec, 2.0, mcap)
    assert len(csv.getvalue().encode()) >= simfiles.file_bytes("csv", 2.0, spec.config.h)
    assert len(mcap.getvalue()) >= simfiles.file_bytes("mcap", 2.0, spec.config.h, 3)


def test_cli_sim_refuses_a_file_larger_than_the_free_disk(tmp_path, capsys):
    from hydromon.cli.main import main

    for opt in ("--to-csv", "--to-mcap"):
        out = tmp_path / ("run.csv" if opt == "--to-csv" else "run.mcap")
        assert main(["sim", "--rigs", "1", "--duration", "1e9", opt, str(out)]) == 2
        err = capsys.readouterr().err
        assert f"{opt} {str(out)!r}: 1e+09 s of" in err and "GB free" in err, err
        assert not out.exists()


def test_file_writers_report_progress_on_long_runs():
    from hydromon.cli.commands.sim import Progress

    now = [0.0]
    out = io.StringIO()
    progress = Progress("--to-csv x.csv", every=5.0, clock=lambda: now[0], stream=out)
    calls = []
    spec = spread_fleet(1, seed=2)

    def on_block(done, total):
        calls.append((done, total))
        now[0] += 2.0  # each block takes 2 s of wall time
        progress(done, total)

    simfiles.write_csv(spec, 50.0, io.StringIO(), on_block=on_block)
    assert calls[-1] == (5000, 5000) and len(calls) == 5  # 1000-sample blocks
    lines = out.getvalue().splitlines()
    assert lines == ["hydromon sim: --to-csv x.csv: 60 % (3000 of 5000 samples), about 4 s to go"], lines
    mcalls = []
    simfiles.write_mcap(spec, 0.25, io.BytesIO(), on_block=lambda d, t: mcalls.append((d, t)))
    assert mcalls == [(25, 25)]


@pytest.mark.network
@pytest.mark.timeout(60)
def test_cli_sim_and_router_stop_by_themselves():
    from hydromon.cli.main import main

    assert main(["router", "--listen", "tcp/127.0.0.1:0", "--duration", "0.2"]) == 0
    assert main(["sim", "--listen", "tcp/127.0.0.1:0", "--rigs", "3", "--rate", "0", "--duration", "0.3"]) == 0


def test_the_framer_cuts_every_sample_once_into_frames_ending_at_each_rigs_phase():
    import orjson

    from hydromon.bus.framer import Framer
    from hydromon.store.fleetfile import spread_fleet
    from monitor.pipeline import eval_phase

    spec = spread_fleet(6, noise="realistic")
    fleet = spec.build()
    framer = Framer(spec.ids, 10, with_u=frozenset({2}))
    got = {i: [] for i in range(6)}
    for k in (7, 13, 10, 3):  # blocks of any sizes: frames span them
        blk = fleet.step(k)
        framer.block(blk)
        for j in range(k):
            for i, payload in framer.due(j):
                got[i].append(orjson.loads(payload))
    for i, payload in framer.rest():
        got[i].append(orjson.loads(payload))
    for i, frames in got.items():
        seqs = [f["seq"] + k for f in frames for k in range(len(f["t"]))]
        assert seqs == list(range(33))  # every sample once, in order
        ends = [f["seq"] + len(f["t"]) - 1 for f in frames[:-1]]
        assert all((e + 1 + eval_phase(spec.ids[i], 10)) % 10 == 0 for e in ends)
        assert all(len(f["t"]) == 10 for f in frames[1:-1]) and ("u" in frames[0]) == (i == 2)
