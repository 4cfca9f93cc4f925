"""Golden recordings (recordings/): each replays, directly, to exactly the health stored in it.

The recordings were made live (recorder and monitor on the bus while the simulator ran, see
hydromon/tools/goldens.py); the health the live monitor published is in them. A direct replay
must give those messages again **byte for byte**, in the same order, and the stored
``.health.jsonl`` must equal them byte for byte too. Bytes, not parsed JSON: the payload is
orjson of the monitor's numbers, which prints every float as its shortest round-trip
decimal, so equal bytes means every estimate, standard error and confidence is bit-identical
and the key order is the same; parsed-JSON equality would be no weaker for the floats but
would hide a change of the payload layout. The failure message shows the first difference.

If a change of the numerics in monitor/ changes the health on purpose, regenerate:
``python -m hydromon.tools.goldens --update`` (one command, rewrites recordings/).
"""

from __future__ import annotations

import orjson
import pytest

from helpers import by_rig, health_seqs
from hydromon.contract import Health
from hydromon.engine.evaluate import evaluate
from hydromon.store.mcap_read import read_recording
from hydromon.store.recording import load_recording
from hydromon.store.replay import health_jsonl, replay_direct
from hydromon.tools.goldens import (
    GOLDENS,
    RECORDINGS_DIR,
    Golden,
    make_golden,
    read_health_jsonl,
    stored_health,
    true_grades,
)
from monitor.evaluations import eval_phase

REGENERATE = ("if the monitor's numerics changed on purpose, run `python -m hydromon.tools.goldens --update` "
              "and commit recordings/")
IDS = [g.name for g in GOLDENS]


def _first_difference(want: list[tuple[str, bytes]], got: list[tuple[str, bytes]]) -> str:
    for i, (w, g) in enumerate(zip(want, got)):
        if w != g:
            if w[0] != g[0]:
                return f"message {i}: key {g[0]!r}, stored {w[0]!r}"
            wd, gd = orjson.loads(w[1]), orjson.loads(g[1])
            diff = {k: (wd.get(k), gd.get(k)) for k in sorted(set(wd) | set(gd)) if wd.get(k) != gd.get(k)}
            if not diff:
                return f"message {i} on {w[0]}: same JSON, different bytes (layout changed)"
            return f"message {i} on {w[0]} (seq {wd.get('seq')}): (stored, replayed) {diff}"[:2000]
    return f"{len(got)} messages replayed, {len(want)} stored"


def _golden_files(g: Golden):
    mcap, jsonl = RECORDINGS_DIR / g.mcap, RECORDINGS_DIR / g.health_file
    for p in (mcap, jsonl):
        assert p.exists(), f"{p} is missing; run `python -m hydromon.tools.goldens --update`"
    return mcap, jsonl


@pytest.fixture(scope="module", params=GOLDENS, ids=IDS)
def golden(request):
    g = request.param
    mcap, jsonl = _golden_files(g)
    replayed, core = replay_direct(mcap)
    return g, stored_health(mcap), replayed, core, jsonl


def test_direct_replay_gives_the_stored_health_byte_for_byte(golden):
    g, stored, replayed, _, _ = golden
    assert len(stored) > 0
    assert replayed == stored, (f"{g.mcap}: a direct replay no longer gives the health the live monitor "
                                f"recorded: {_first_difference(stored, replayed)}; {REGENERATE}")


def test_health_jsonl_is_the_stored_health(golden):
    g, stored, _, _, jsonl = golden
    assert read_health_jsonl(jsonl) == stored, f"{g.health_file}: {_first_difference(stored, read_health_jsonl(jsonl))}"
    assert jsonl.read_bytes() == b"".join(health_jsonl(stored)), f"{g.health_file}; {REGENERATE}"


def test_every_rig_ends_at_its_true_grade_and_the_input_was_whole(golden):
    g, stored, replayed, core, _ = golden
    truth = true_grades(g)
    assert sorted(core.latest) == sorted(truth) == sorted(g.fleet.ids)
    final = {rig: Health.model_validate_json(p) for rig, p in core.latest.items()}
    assert {r: h.grade for r, h in final.items()} == truth, REGENERATE
    assert all(h.status == "ok" for h in final.values())
    # the recording holds every sample the sim published (no loss on the bus), every config,
    # and every verdict; gaps and restarts are exactly the golden's segments
    c = core.counters
    per_rig = sum(round(s.seconds * 100) for s in g.segments)
    assert c.accepted == per_rig * len(g.fleet.rigs)
    assert c.rejected_total == 0 and c.dropped_seq == 0
    assert c.gaps == sum(s.skip > 0 for s in g.segments) * len(g.fleet.rigs)
    assert c.missing == sum(round(s.skip * 100) for s in g.segments) * len(g.fleet.rigs)
    assert c.restarts == sum(s.restart for s in g.segments) * len(g.fleet.rigs)
    assert c.configs == len(g.segments) * len(g.fleet.rigs)  # the sim node sends them as it starts
    # the recorded verdicts and their events go in, and are skipped as the monitors' own output
    events = [k for k, _, _, _ in read_recording(RECORDINGS_DIR / g.mcap) if k.endswith("/event")]
    assert events and c.ignored == len(stored) + len(events)
    for h in map(Health.model_validate_json, (p for _, p in stored)):  # finite, contract-valid payloads
        assert h.status in ("converging", "ok", "stale")


def test_gap_and_restart_show_in_the_health():
    (g,) = [g for g in GOLDENS if g.name == "gap-restart"]
    stored = stored_health(_golden_files(g)[0])
    (rig,) = {k.split("/")[2] for k, _ in stored}
    hs = [orjson.loads(p) for _, p in stored]
    seqs = [h["seq"] for h in hs]
    # 5 s (seq 0..499), the dropout (500..549 never sent), 5 s (550..1049), a restart (0..599);
    # windows count the rig's samples, staggered by its phase
    ph = eval_phase(rig, 10)
    after_gap = [q for q in range(550, 1050) if (q - 50 + 1 + ph) % 10 == 0]
    assert seqs == health_seqs(rig, 500) + after_gap + health_seqs(rig, 600)
    assert [h["seq"] for h in hs if h["status"] == "stale"] == after_gap[:1]  # the first verdict after the gap
    n1 = len(health_seqs(rig, 500))
    after = hs[-len(health_seqs(rig, 600)):]
    assert after[:n1] == hs[:n1]
    assert hs[n1 - 1]["grade"] == hs[-len(after) - 1]["grade"] == after[-1]["grade"] == "average"


def test_a_rig_sending_frames_gets_the_health_it_gets_sending_samples():
    """The framed golden's rigs are table4-realistic's first two, same noise: each rig's recorded
    health is, byte for byte, what it was given for its first 5 s of samples."""
    (framed,) = [g for g in GOLDENS if g.frame is not None]
    (samples,) = [g for g in GOLDENS if g.name == "table4-realistic"]
    got, want = by_rig(stored_health(_golden_files(framed)[0])), by_rig(stored_health(_golden_files(samples)[0]))
    assert sorted(got) == framed.fleet.ids and len(got["table4-g1"]) == 50
    kinds = {k.rsplit("/", 1)[1] for k, _, _, _ in read_recording(RECORDINGS_DIR / framed.mcap)}
    assert "frame" in kinds and "sample" not in kinds
    for rig, payloads in got.items():
        assert payloads == want[rig][:len(payloads)], f"{rig}: {_first_difference(want[rig], payloads)}"


def test_the_recordings_directory_holds_exactly_the_goldens():
    want = {"README.md"} | {g.mcap for g in GOLDENS} | {g.health_file for g in GOLDENS}
    have = {p.name for p in RECORDINGS_DIR.iterdir() if not p.name.startswith(".")}
    assert have == want, f"unexpected {sorted(have - want)}, missing {sorted(want - have)}"
    total = sum((RECORDINGS_DIR / n).stat().st_size for n in want)
    assert total < 2.5e6  # small: the repository carries them


@pytest.mark.parametrize("name", ["table4-clean", "table4-realistic"])
def test_evaluate_grades_each_rig_of_the_recording_at_its_true_grade(name):
    (g,) = [g for g in GOLDENS if g.name == name]
    mcap, _ = _golden_files(g)
    for rig, truth in true_grades(g).items():
        ev = evaluate(load_recording(mcap, rig=rig))
        assert ev.assessment.grade == truth, f"hydromon evaluate {mcap} --rig {rig}"


def test_cli_direct_replay_prints_the_health_jsonl(tmp_path, capsys):
    from hydromon.cli.main import main

    (g,) = [g for g in GOLDENS if g.name == "gap-restart"]
    mcap, jsonl = _golden_files(g)
    out = tmp_path / "h.jsonl"
    assert main(["replay", str(mcap), "--direct", "--out", str(out)]) == 0
    assert out.read_bytes() == jsonl.read_bytes(), REGENERATE
    assert "table4-g4: average" in capsys.readouterr().err
    # the live monitor's ranges given explicitly: the same bytes; other ranges: other grades
    assert main(["replay", str(mcap), "--direct", "--out", str(out), "--ranges", "default"]) == 0
    assert out.read_bytes() == jsonl.read_bytes()
    assert main(["replay", str(mcap), "--direct", "--out", str(out), "--ranges", "paper"]) == 0
    last = orjson.loads(out.read_bytes().splitlines()[-1])
    assert "K_sv_omega_sv2" in last["health"]["param_grades"] and "K_sv" not in last["health"]["param_grades"]


@pytest.mark.network
@pytest.mark.timeout(300)
def test_regenerating_a_golden_gives_the_committed_health(tmp_path):
    """``--update`` is deterministic: a fresh live recording of the same rigs holds the same
    verdicts, byte for byte (the recording's log times differ, the health does not)."""
    (g,) = [g for g in GOLDENS if g.name == "gap-restart"]
    _, jsonl = _golden_files(g)
    made = make_golden(g, tmp_path / g.mcap, rate=0)
    assert made.health == read_health_jsonl(jsonl), f"{_first_difference(read_health_jsonl(jsonl), made.health)}; " \
                                                    f"{REGENERATE}"
    kinds = [k.rsplit("/", 1)[1] for k, _, _, _ in read_recording(made.path)]
    assert kinds.count("sample") == 1600 and kinds.count("health") == 160 and kinds.count("config") == 3
