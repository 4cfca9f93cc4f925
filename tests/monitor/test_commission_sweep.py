"""A subset of the commissioning sweep (``python -m hydromon.tools.commission_sweep``): rigs that
are not the reference rig, each commissioned from a healthy 30 s record and graded at the five
grades; every input profile and both noise models, on the sweep's held-out seed."""

import pytest

from hydromon.contract import GRADES
from hydromon.tools.commission_sweep import PROFILES, sweep_rig

SEED = 7  # the sweep's held-out seed (docs/commissioning.md)


@pytest.mark.timeout(600)
def test_commissioned_rigs_of_other_sizes_are_graded_right_on_every_profile_and_noise():
    outcomes = [o for i, noise in enumerate(("realistic", "stress", "realistic", "stress"))
                for o in sweep_rig(i, noise, seed=SEED)]
    assert {o.profile for o in outcomes} == set(PROFILES) and {o.truth for o in outcomes} == set(GRADES)
    right = sum(o.right for o in outcomes)
    wrong = [(o.rig, o.profile, o.noise, o.truth, o.grade) for o in outcomes if not o.right]
    assert right >= 0.9 * len(outcomes), wrong  # the target the sweep is held to
    assert all(o.grade != "unknown" for o in outcomes), wrong  # every one was commissioned and graded
