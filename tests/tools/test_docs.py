"""The generated docs are up to date with what they are generated from."""

from __future__ import annotations

from hydromon.cli import reference
from hydromon.tools import docs_gen


# -- docs -----------------------------------------------------------------------------------
def test_docs_contract_md_is_up_to_date():
    assert docs_gen.DOC_PATH.read_text() == docs_gen.render(), "run `python -m hydromon.tools.docs_gen`"


def test_docs_cli_md_is_up_to_date():
    assert reference.DOC_PATH.read_text() == reference.render(), "run `python -m hydromon.cli.reference`"


def test_docs_cli_md_does_not_depend_on_the_terminal_width(monkeypatch):
    texts = set()
    for columns in ("40", "300"):
        monkeypatch.setenv("COLUMNS", columns)
        texts.add(reference.render())
    assert texts == {reference.render()}


def test_docs_cli_md_has_every_command():
    from hydromon.cli.main import build_parser

    (sub,) = [a for a in build_parser()._actions if a.dest == "command"]
    text = reference.render()
    for name in sub.choices:
        assert f"\n## hydromon {name}\n" in text and f"usage: hydromon {name} " in text
