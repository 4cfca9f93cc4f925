"""Which ranges grade which rig: a rig's own ranges when made for its constants, the default
ranges for the rig they were made for, none otherwise (uncalibrated, with a hint); a watched
directory of per-rig files, its bad files refused without losing the good ones."""

import json

from hydromon.contract import RigConfig
from hydromon.engine.ranges_book import COMMISSION_HINT, RangesBook
from hydromon.store.ranges_dir import RangesDir
from monitor.ranges import Ranges
from monitor.relative import REFERENCE_HEALTHY, relative_ranges

OTHER = RigConfig(A1=0.012, p_s=16e6)


def _own(config=OTHER):
    return relative_ranges(dict(REFERENCE_HEALTHY, K_sv=1.4e-4), config)[0].model_copy(update={"created": "2026-01-02"})


def test_the_default_grades_only_the_reference_rig_and_a_rigs_own_ranges_only_it():
    book = RangesBook()
    assert book.for_rig("a", None).tag == "default" and book.for_rig("a", RigConfig()).ranges == Ranges.default()
    none = book.for_rig("b", OTHER)
    assert none.ranges is None and "A1 0.012" in none.why and COMMISSION_HINT in none.why
    book.set("b", _own(), "b.json")
    assert book.for_rig("b", OTHER).tag == "b.json"
    wrong = book.for_rig("b", RigConfig())  # its own ranges, but the rig's constants changed
    assert wrong.ranges is None and "its ranges b.json do not apply" in wrong.why


def test_a_watched_directory_gives_new_changed_and_removed_files_and_refuses_bad_ones(tmp_path):
    d = RangesDir(tmp_path)
    assert d.scan() == []
    (tmp_path / "b.json").write_text(_own().model_dump_json())
    (tmp_path / "not a rig.json").write_text("{}")
    (tmp_path / ".b.json.part").write_text("half")
    [c] = d.scan()
    assert c.rig_id == "b" and c.ranges == _own() and c.tag == "b.json (2026-01-02)"
    assert d.scan() == []  # nothing changed
    (tmp_path / "b.json").write_text('{"params": 3}')
    [bad] = d.scan()
    assert bad.ranges is None and "bad ranges file" in bad.error and not bad.removed
    (tmp_path / "b.json").write_text(json.dumps({"params": Ranges.default().model_dump()["params"]}))
    [norig] = d.scan()
    assert "names no rig constants" in norig.error
    (tmp_path / "b.json").unlink()
    [gone] = d.scan()
    assert gone.removed and gone.rig_id == "b"
