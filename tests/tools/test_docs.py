"""The generated docs are up to date with what they are generated from."""

from __future__ import annotations

from hydromon.tools import docs_gen


# -- docs -----------------------------------------------------------------------------------
def test_docs_contract_md_is_up_to_date():
    assert docs_gen.DOC_PATH.read_text() == docs_gen.render(), "run `python -m hydromon.tools.docs_gen`"
