"""The contract's key codec: rig keys built and parsed, and why a key is not one."""

from __future__ import annotations

import pytest


@pytest.mark.parametrize("key, want", [
    ("hydro/rig/a-1/sample", ("a-1", "sample")), ("hydro/rig/a/health", ("a", "health")),
    ("site/rig/a/sample", "bad-key: not under hydro/rig/"), ("hydro/rig/a/sample/x", "bad-key: expected"),
    ("hydro/rig/a/state", "bad-key: expected"), ("hydro/rig/a b/config", "bad-rig-id: 'a b'"),
    ("hydro/rig/" + "x" * 65 + "/sample", "bad-rig-id: "),
])
def test_split_rig_key_says_why_a_key_is_not_a_rig_key(key, want):
    # the one parser of rig keys: the monitor's rejection reasons come from it
    from hydromon.contract import parse_rig_key, split_rig_key

    got = split_rig_key(key)
    assert got == want if isinstance(want, tuple) else got.startswith(want)
    assert parse_rig_key(key) == (want if isinstance(want, tuple) else None)
