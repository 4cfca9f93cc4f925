"""A failover group's tokens on a real zenoh session (loopback): a token that is not a claim as
monitors make them (``<claim time [ns], 20 digits>-<node>``) claims nothing and stops nothing."""

from __future__ import annotations

import time

import pytest

from helpers import wait_for
from hydromon.bus.failover import Failover
from hydromon.bus.session import listening_session, open_session

BAD = ("0", "x", "-", "0-", "12-evil", "00000000000000000000-", "00000000000000000000-a b",
       "00000000000000000000-" + "n" * 65, "notdigits0000000000-evil")


@pytest.mark.network
@pytest.mark.timeout(60)
def test_tokens_that_are_not_claims_neither_crash_nor_stop_a_monitor():
    with listening_session() as (mine, ep), open_session("peer", connect=[ep]) as other:
        tokens = [other.liveliness().declare_token(f"hydro/failover/all/{name}") for name in BAD[1:]]
        wait_for(lambda: len(list(mine.liveliness().get("hydro/failover/all/*", timeout=1.0))) == len(tokens), 10,
                 "the tokens seen")
        # a monitor starting while they live claims the group at once
        fo = Failover(mine, "hydro", "all", "m1")
        assert fo.poll() == "no other monitor publishes for these rigs: publishing" and fo.active
        # and one declared while it publishes leaves it publishing
        tokens.append(other.liveliness().declare_token("hydro/failover/all/0"))
        for _ in range(20):
            time.sleep(0.05)
            assert fo.poll() is None and fo.active
        # a well-formed older claim still makes it stand back: the rule the tokens carry
        tokens.append(other.liveliness().declare_token("hydro/failover/all/00000000000000000001-m0"))
        lines = []
        wait_for(lambda: lines.append(fo.poll()) or not fo.active, 10, "the older claim seen")
        assert "monitor m0 claimed these rigs first: standing by" in lines and fo.holder() == "m0"
        for tok in tokens:
            tok.undeclare()
        fo.close()
