"""A monitor that joins a running rig: the valve's gain must still be graded.

The paper's 1 Hz identification input excites the spool's dynamics (100 rad/s) only at the
start from rest. Started 1 s into the run, K_sv omega^2 and omega^2 are off by up to 2x (their
SE covers it, so they are not placed), while the static gain K_sv is exact: it is what grades
a valve that lost gain.
"""

from __future__ import annotations

import numpy as np
import pytest

from hydromon.contract import RigConfig
from monitor.grading import Ranges, grade_of_values
from monitor.pipeline import Fleet
from plant_sim.noise import noise_model
from plant_sim.params import PlantParams
from plant_sim.profiles import PaperIdentification
from plant_sim.simulate import simulate_fleet

START = 100  # [samples] the monitor joins 1 s into the run
K_SV = (2.5e-4, 1.9e-4, 1.2e-4)  # [m/V] health, sub-health, deterioration under Table 3
SEEDS = 3


@pytest.fixture(scope="module")
def midrun():
    plants = [PlantParams(K_sv=k) for k in K_SV for _ in range(SEEDS)]
    runs = simulate_fleet(RigConfig(), plants, [PaperIdentification()] * len(plants), 10.0 + START / 100,
                          noise=noise_model("realistic"), seeds=list(range(len(plants))))
    return plants, runs


def _fleet(runs, ranges=None):
    fleet = Fleet(ranges=ranges)
    for i in range(len(runs)):
        fleet.add_rig(f"r{i}")
    events = [fleet.update(np.full(len(r.samples) - START, i), r.samples[START:]) for i, r in enumerate(runs)]
    return fleet, events


def test_a_valve_that_lost_gain_is_graded_when_the_monitor_joins_mid_run(midrun):
    plants, runs = midrun
    fleet, events = _fleet(runs)
    for i, p in enumerate(plants):
        a = fleet.estimate(i)
        want = grade_of_values(p.identified())
        assert a.level == want, (p.K_sv, a.grade, a.param_grades)
        # and fast: graded 3.5 s after the monitor's first sample (measured: 350 samples for
        # every rig), the true grade from its first one on
        graded = events[i].level >= 0
        assert graded.any() and events[i].counts[graded][0] <= 400
        assert (events[i].level[graded] == want).all(), events[i].level[graded]
        assert a.param_grades["K_sv"] == a.grade
        k, se = a.params["K_sv"], a.std_errors["K_sv"]
        assert abs(k - p.K_sv) <= 3 * se, (k, se, p.K_sv)
        assert se < 0.01 * p.K_sv


def test_graded_on_k_sv_omega2_as_printed_the_lost_gain_goes_unseen(midrun):
    """The counter-check: graded by the paper's Table 3 as printed (K_sv omega^2), the same
    records miss the worn valve. A statement of today's limit (the valve's dynamics are not
    identified without excitation): if that is ever fixed, this test should change with it."""
    plants, runs = midrun
    fleet, _ = _fleet(runs, Ranges.paper())
    worn = [i for i, p in enumerate(plants) if p.K_sv < 1.4e-4]
    assert all(fleet.estimate(i).level < 3 for i in worn)
    assert all(fleet.estimate(i).param_grades.get("K_sv_omega_sv2", "unknown") == "unknown" for i in worn)
