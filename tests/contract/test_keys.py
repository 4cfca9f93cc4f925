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


def test_a_liveliness_token_names_a_monitor_only_with_a_node_name():
    from hydromon.contract import monitor_of_token

    assert monitor_of_token("hydro/monitor/mon-1") == "mon-1"
    assert monitor_of_token("site/a/monitor/m_2") == "m_2"
    for bad in ("hydro/monitor/<img src=x onerror=alert(1)>", "hydro/monitor/a b", "hydro/monitor/\u202eevil",
                "hydro/monitor/" + "n" * 65, "hydro/monitor/"):
        assert monitor_of_token(bad) is None, bad
