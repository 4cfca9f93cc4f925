"""Model audit: hidden effects must be named, clean records must give "none".

The hidden-effect cases are seeded; their magnitudes are "moderate" as defined in
``hidden_case`` (documented there). The 40-case sweep runs in CI; the 40 clean records are slow.
"""

from __future__ import annotations

import io
import json
import os
import tempfile

import numpy as np
import pytest

from hydromon.cli.commands.audit import read_csv
from hydromon.report.audit import to_json, write_report
from monitor.audit import LIBRARY, AuditOptions, audit
from plant_sim.degradation import degrade
from plant_sim.noise import noise_model
from plant_sim.params import EFFECT_NAMES, Effects
from plant_sim.profiles import parse_profile
from plant_sim.simulate import simulate

CASE_NAMES = ("none",) + EFFECT_NAMES
PROFILES = ("paper-var", "paper-id", "steps", "chirp", "multisine")
DURATION = 30.0  # [s]


def hidden_case(seed: int, name: str | None = None, noise: str = "realistic"):
    """A seeded record with one hidden effect (or none).

    Random: the effect (unless given), the health severity in [0, 1) (all five bands), the
    profile, and u in [0, 1] setting the magnitude:
    Stribeck peak 150..450 N at v_s 5..20 mm/s; spool stop at 70..100 % of the 95th
    percentile of the unsaturated |x5| (so the stop acts on at least 5 % of the samples; a
    stop only a rare spike reaches is not an effect the record shows); overlap 15..45 um;
    supply resistance 4e9..1e10 Pa/(m^3/s); air
    fraction 0.08..0.2; position delay 1..5 samples in or outside the loop; load offset
    +-(300..1500) N. Realistic sensor noise unless ``noise`` says otherwise.
    """
    rng = np.random.default_rng(seed)
    if name is None:
        name = CASE_NAMES[int(rng.integers(len(CASE_NAMES)))]
    severity = float(rng.uniform(0.0, 1.0))
    profile = parse_profile(PROFILES[int(rng.integers(len(PROFILES)))])
    u = float(rng.uniform())
    params = degrade(severity)
    e = {}
    if name == "stribeck_friction":
        e = dict(stribeck_F_s=150 + 300 * u, stribeck_v_s=float(rng.uniform(0.005, 0.02)))
    elif name == "valve_saturation":
        free = simulate(profile, DURATION, params=params)
        e = dict(x_max=float(np.quantile(np.abs(free.states[:, 4]), 0.95) * (0.7 + 0.3 * u)))
    elif name == "valve_dead_band":
        e = dict(dead_band=1.5e-5 + 3e-5 * u)
    elif name == "supply_pressure_sag":
        e = dict(supply_sag=4e9 + 6e9 * u)
    elif name == "entrained_air":
        e = dict(air_fraction=0.08 + 0.12 * u)
    elif name == "sensor_delay":
        e = dict(sensor_delay=int(rng.integers(1, 6)), sensor_delay_in_loop=bool(rng.integers(2)))
    elif name == "load_offset":
        e = dict(load_offset=float(rng.choice([-1.0, 1.0]) * (300 + 1200 * u)))
    run = simulate(profile, DURATION, params=params, effects=Effects(**e),
                   noise=noise_model(noise), seed=seed)
    return name, run


def test_library_has_one_named_object_per_effect():
    names = [c.name for c in LIBRARY]
    assert sorted(names) == sorted(EFFECT_NAMES)
    for c in LIBRARY:
        assert c.equation and c.regressors and c.n_extra >= 1


@pytest.mark.parametrize("seed", [1, 2])
def test_clean_record_gives_none(seed):
    _, run = hidden_case(seed, "none")
    res = audit(run.samples, run.config)
    assert res.cause == "none", [(c.name, round(c.score, 1)) for c in res.candidates]
    assert res.unfitted == {} and len(res.candidates) == len(LIBRARY)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_short_clean_record_gives_none(tmp_path, seed):
    """`hydromon sim --severity 0 --duration 20 --noise realistic --seed S` then `hydromon audit`
    names no cause. Without the rest block's variance floor, one noise excursion among the 20
    held-out rest rows (which any wider dead zone absorbs) named stribeck_friction (seed 0) and
    load_offset (seed 1), both confident; the floor counts one such row as noise."""
    from hydromon.cli.main import main
    from hydromon.store.recording import load_recording

    path = tmp_path / "clean.csv"
    assert main(["sim", "--severity", "0", "--duration", "20", "--noise", "realistic", "--seed", str(seed),
                 "--to-csv", str(path)]) == 0
    rec = load_recording(path)
    res = audit(rec.samples, rec.config, AuditOptions(free_run=False))
    assert res.cause == "none", [(c.name, round(c.score, 2)) for c in res.candidates]


def test_noise_free_clean_record_gives_none():
    """Tiny filter-approximation errors of a noise-free record are no evidence (variance floors)."""
    name, run = hidden_case(2001, noise="none")  # a drawn clean case that a ratio of tiny errors misnamed
    assert name == "none"
    res = audit(run.samples, run.config, AuditOptions(free_run=False))
    assert res.cause == "none", [(c.name, round(c.score, 2)) for c in res.candidates]


@pytest.mark.parametrize("name,seed", [
    ("load_offset", 3), ("sensor_delay", 4), ("valve_saturation", 5), ("valve_dead_band", 6),
])
def test_clear_effects_are_named(name, seed):
    _, run = hidden_case(seed, name)
    res = audit(run.samples, run.config)
    assert res.cause == name, [(c.name, round(c.score, 1)) for c in res.candidates]


def test_sensor_delay_tells_loop_from_recording():
    for loop in (False, True):
        run = simulate(parse_profile("multisine"), DURATION, params=degrade(0.3),
                       effects=Effects(sensor_delay=3, sensor_delay_in_loop=loop),
                       noise=noise_model("realistic"), seed=11)
        res = audit(run.samples, run.config)
        assert res.cause == "sensor_delay"
        assert res.best.effect == {"sensor_delay": 3, "sensor_delay_in_loop": loop}


def test_load_offset_value_and_gain():
    run = simulate(parse_profile("paper-var"), DURATION, params=degrade(0.3),
                   effects=Effects(load_offset=1000.0), noise=noise_model("realistic"), seed=5)
    res = audit(run.samples, run.config)
    assert res.cause == "load_offset"
    assert abs(res.best.effect["load_offset"] - 1000.0) < 100.0
    assert res.best.residual_ratio["force"] < 0.5


def test_json_and_report(tmp_path):
    _, run = hidden_case(3, "load_offset")
    res = audit(run.samples, run.config)
    doc = json.loads(json.dumps(to_json(res)))
    assert set(doc) >= {"cause", "candidates", "gain", "params_nominal", "params_extended"}
    assert {c["name"] for c in doc["candidates"]} == set(EFFECT_NAMES)
    assert all(set(c) >= {"name", "score", "twin", "gain"} for c in doc["candidates"])
    assert "load_offset" in doc["params_extended"]
    md = write_report(res, tmp_path / "rep")
    assert md.exists() and (tmp_path / "rep" / "freerun.png").exists()
    assert "load_offset" in md.read_text()


def test_bad_input_raises():
    with pytest.raises(ValueError, match="samples"):
        audit(np.zeros((100, 4)))
    bad = np.ones((500, 5))
    bad[7, 2] = np.nan
    with pytest.raises(ValueError, match="sample 7"):
        audit(bad)
    with pytest.raises(ValueError, match="train_fraction"):
        AuditOptions(train_fraction=1.5)
    with pytest.raises(ValueError, match="header"):
        read_csv(io.StringIO("a,b\n1,2\n"))


def test_cli_csv_roundtrip(tmp_path, capsys):
    from hydromon.cli.main import main

    _, run = hidden_case(3, "load_offset")
    path = tmp_path / "rec.csv"
    write_csv(path, run)
    assert main(["audit", str(path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["cause"] == "load_offset"


def test_cli_exits_1_on_a_record_that_does_not_obey_the_model(tmp_path, capsys):
    from hydromon.cli.main import main

    _, run = hidden_case(3, "load_offset")
    path = tmp_path / "neg.csv"
    from types import SimpleNamespace
    write_csv(path, SimpleNamespace(t=run.t, samples=run.samples * np.array([1, -1, 1, 1, 1])))  # x1's sign turned
    assert main(["audit", str(path), "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)  # still reported in full
    assert doc["cause"] == "unexplained" and "does not obey the model" in doc["note"]
    assert not doc["obeys_model"] and "chamber equation" in doc["note"]


def test_cli_prints_the_result_before_a_report_that_fails(tmp_path, capsys, monkeypatch):
    import errno

    from hydromon.cli.main import main
    from hydromon.report import audit as audit_report

    def disk_full(result, directory, *what):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(audit_report, "write_report", disk_full)
    _, run = hidden_case(3, "load_offset")
    path = tmp_path / "rec.csv"
    write_csv(path, run)
    assert main(["audit", str(path), "--json", "--report", str(tmp_path / "rep")]) == 2
    out, err = capsys.readouterr()
    assert json.loads(out)["cause"] == "load_offset"  # the work is not lost with the report
    assert "No space left on device (the result above is complete)" in err


def test_cli_mcap(tmp_path, capsys):
    from hydromon.cli.main import main
    from hydromon.store.fleetfile import spread_fleet
    from hydromon.store.simfiles import write_mcap

    spec = spread_fleet(1, profile="paper-var", noise="realistic").with_overrides(
        severity=0.3, effects={"load_offset": 1000.0})
    path = tmp_path / "rec.mcap"
    with open(path, "wb") as f:
        write_mcap(spec, DURATION, f)
    assert main(["audit", str(path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["cause"] == "load_offset"



def test_audit_reads_a_record_as_evaluate_does(tmp_path, capsys):
    """The audit reads a file as ``hydromon evaluate`` does: a re-sent (duplicate) MCAP message is
    dropped (not "t does not increase strictly"), only the samples after a config change are taken,
    with its constants, t in ms is refused before the work (not "force equation: only 0 training
    rows" after it), and --config's sample_rate is kept (not replaced by the file's median
    interval)."""
    from hydromon.cli.commands.audit import load
    from hydromon.cli.main import main
    from hydromon.store.mcap_write import RecordingWriter
    from hydromon.store.recording import load_recording

    run = simulate(parse_profile("paper-var"), 3.0, noise=noise_model("realistic"), seed=1)
    other = run.config.model_copy(update={"V10": 0.12})
    path = tmp_path / "rec.mcap"
    with open(path, "wb") as f, RecordingWriter(f) as w:
        w.write("hydro/rig/r1/config", run.config.model_dump_json().encode(), 0, 0)
        for k, (t, row) in enumerate(zip(run.t, run.samples)):
            t_ns = int(round(t * 1e9))
            if k == 100:
                w.write("hydro/rig/r1/config", other.model_dump_json().encode(), t_ns, t_ns)
            payload = json.dumps(dict(seq=k, t=float(t), **dict(zip(("ug", "x1", "x3", "x4", "x5"),
                                                                     map(float, row))))).encode()
            w.write("hydro/rig/r1/sample", payload, t_ns, t_ns)
            if k == 200:  # the same message twice
                w.write("hydro/rig/r1/sample", payload, t_ns + 1, t_ns + 1)
    config, samples, stretch = load(str(path))
    assert stretch is None
    rec = load_recording(path)
    assert config == other == rec.config
    np.testing.assert_array_equal(samples, run.samples[100:])
    assert "config changed 1 time(s): auditing the 200 samples after the last change" in capsys.readouterr().err

    ms = tmp_path / "ms.csv"
    ms.write_text("t,ug,x1,x3,x4,x5\n" + "".join(",".join(repr(float(v)) for v in (1e3 * t, *row)) + "\n"
                                                 for t, row in zip(run.t, run.samples)))
    assert main(["audit", str(ms)]) == 2
    assert "t looks like milliseconds" in capsys.readouterr().err
    csv = tmp_path / "rec.csv"
    write_csv(csv, run)
    conf = tmp_path / "rig.json"
    conf.write_text(json.dumps({"sample_rate": 200.0}))
    assert main(["audit", str(csv), "--config", str(conf)]) == 2
    assert "not 200 Hz" in capsys.readouterr().err

def test_across_a_gap_the_audit_takes_the_longest_stretch_and_says_so(tmp_path, capsys):
    """One invalid sample (x3 = 5e9 Pa) leaves a gap, which does not make a recording
    un-auditable: the audit takes the longest stretch without a gap, as evaluate --refine does,
    and names it on stderr and in the JSON."""
    from hydromon.cli.commands.audit import load
    from hydromon.cli.main import main

    run = simulate(parse_profile("paper-var"), 4.0, noise=noise_model("realistic"), seed=3)
    rows = run.samples.copy()
    path = tmp_path / "gap.csv"
    with open(path, "w") as f:  # samples 100 and 101 missing: stretches 0..99 and 102..399
        f.write("t,ug,x1,x3,x4,x5\n")
        for k, (t, row) in enumerate(zip(run.t, rows)):
            if k not in (100, 101):
                f.write(",".join(repr(float(v)) for v in (t, *row)) + "\n")
    config, samples, stretch = load(str(path))
    np.testing.assert_array_equal(samples, run.samples[102:])
    assert stretch["first"] == 100 and stretch["last"] == 397 and stretch["samples"] == 298 and stretch["of"] == 398
    assert stretch["gaps"] == 1 and stretch["missing"] == 2 and stretch["where"] == "line 102 to line 399"
    err = capsys.readouterr().err
    assert "1 gap(s) (2 sample(s) missing): auditing the longest stretch without one, line 102 to line 399" in err
    assert "t = 1.02 to 3.99 s, 298 of 398 samples" in err
    assert main(["audit", str(path), "--json", "--train-fraction", "0.7"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["stretch"] == stretch and doc["cause"] in {c.name for c in LIBRARY} | {"none"}


def write_csv(path, run) -> None:
    """The record as the user's CSV (t,ug,x1,x3,x4,x5 in SI; floats written exactly)."""
    with open(path, "w") as f:
        f.write("t,ug,x1,x3,x4,x5\n")
        for t, row in zip(run.t, run.samples):
            f.write(",".join(repr(float(v)) for v in (t, *row)) + "\n")


def _sweep(seeds):
    """Each hidden case goes to the audit as a CSV file only, as a user's record would."""
    from hydromon.cli.commands.audit import load

    hits, none_named, gains, rows = 0, 0, [], []
    with tempfile.TemporaryDirectory() as tmp:
        results = []
        for seed in seeds:
            name, run = hidden_case(seed)
            path = os.path.join(tmp, f"case-{seed}.csv")
            write_csv(path, run)
            config, samples, _ = load(path)
            results.append((seed, name, audit(samples, config)))
    for seed, name, res in results:
        hits += res.cause == name
        none_named += name == "none" and res.cause != "none"
        if res.best is not None and res.cause == name:
            gains.append(res.best.gain)
        rows.append((seed, name, res.cause))
    return hits, none_named, gains, rows


@pytest.mark.slow
def test_clean_records_sweep_40():
    """No clean record (random severity and profile) is named as an effect."""
    named = []
    for seed in range(3000, 3040):
        _, run = hidden_case(seed, "none")
        res = audit(run.samples, run.config, AuditOptions(free_run=False))
        if res.cause != "none":
            named.append((seed, res.cause))
    assert not named, named


@pytest.fixture(scope="module")
def sweep_40():
    """The 40 seeded hidden cases (about 40 s), run once for the tests below."""
    return _sweep(range(2000, 2040))


def test_hidden_effects_sweep_40(sweep_40):
    """The acceptance bar, in CI: 40 seeded hidden cases, >= 90 % named right, no clean record
    named, the median held-out free-run error reduction of the named effects >= 50 %."""
    hits, none_named, gains, rows = sweep_40
    assert none_named == 0, rows
    assert hits >= 0.9 * 40, rows
    assert np.median(gains) >= 0.5, gains


def test_every_named_effect_improves_the_free_run(sweep_40):
    """Every named effect's extended model simulates the held-out part better than the nominal
    model (the acceptance criterion; Stribeck friction needs the output-error refinement of its
    friction for that, see monitor.audit.audit._output_error)."""
    _, _, gains, _ = sweep_40
    assert all(g > 0 for g in gains), gains


@pytest.mark.parametrize("what, scale", [("x1 ten times too large", (1, 10, 1, 1, 1)),
                                         ("x1's sign turned", (1, -1, 1, 1, 1)),
                                         ("x5's sign turned", (1, 1, 1, 1, -1))])
def test_a_record_in_wrong_units_or_signs_names_no_cause(what, scale):
    # such a record does not obey the model: the audit says so and names no cause (x1 in mm and
    # pressures in bar are refused before anything is fitted: test_audit_auditable.py)
    _, run = hidden_case(3, "load_offset")
    res = audit(run.samples * np.array(scale), run.config)
    assert res.cause == "unexplained" and not res.confident and not res.obeys, (what, res.cause, res.note)
    assert "does not obey the model" in res.note, what
    # the same record in SI still names its effect
    assert audit(run.samples, run.config).cause == "load_offset"


def test_audit_reports_its_stages_and_a_long_audit_says_so_on_stderr():
    # a one-hour record audits for about 95 s: the audit reports its progress on stderr meanwhile
    from hydromon.cli.commands.audit import Progress

    _, run = hidden_case(2001, noise="none")
    calls = []
    audit(run.samples, run.config, AuditOptions(free_run=False), library=LIBRARY[:3],
          progress=lambda *a: calls.append(a))
    names = [c.name for c in LIBRARY[:3]]
    assert calls == [(0, 3, "nominal"), *[(i + 1, 3, n) for i, n in enumerate(names)]]

    now, out = [0.0], io.StringIO()
    p = Progress(every=5.0, clock=lambda: now[0], stream=out)
    for t, (done, total, name) in zip([1.0, 6.0, 8.0, 12.0], calls):
        now[0] = t
        p(done, total, name)
    # quiet for the first 5 s, then at most every 5 s (not at 8 s), and nothing once done
    assert out.getvalue().splitlines() == [
        f"hydromon audit: 1 of 3 candidate extensions tried (last {names[0]}), 6 s so far"]
