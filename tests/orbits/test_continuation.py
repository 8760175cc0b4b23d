"""Families of orbits over a parameter, their stability changes and where they end."""

import numpy as np

from helpers.orbit_systems import APEX, G, hopping_ball
from legsim.orbits import OrbitProblem, continue_family


def test_continuation_finds_the_period_doubling_of_the_hopping_ball():
    D = 4.0
    prob = OrbitProblem(hopping_ball, APEX, h=1e-2, eps=1e-4, t_max=4.0, parameters={"kick": D, "k": 0.5})
    fam = continue_family(prob, "k", 0.6, 1.4, 8, {"z": 0.3})
    assert fam.complete, fam.message
    assert [round(p.value, 12) for p in fam.points] == [round(v, 12) for v in np.linspace(0.6, 1.4, 9)]
    for p in fam.points:
        v = D / (1 + p.value)
        assert abs(p.result.fixed_point[0] - v**2 / (2 * G)) < 1e-9
        assert abs(p.result.multipliers[0] - (-p.value)) < 1e-6
    assert len(fam.stability_changes) == 1
    change = fam.stability_changes[0]
    assert change.becomes == "unstable" and "period doubling" in change.kind
    assert abs(change.at - 1.0) < 1e-6  # |multiplier| = k is linear in k: interpolation is exact


def test_continuation_stops_with_a_reason_where_the_family_ends():
    # The kick D = 4 launches the ball only while v* = D / (1 + k) > 0 ... always; instead end the
    # family by a time limit: the period 2 v* / g exceeds t_max = 0.5 s once v* > 2.45 m/s,
    # i.e. k < 0.63.
    prob = OrbitProblem(hopping_ball, APEX, h=1e-2, eps=1e-4, t_max=0.5, parameters={"kick": 4.0, "k": 1.0})
    fam = continue_family(prob, "k", 1.0, 0.3, 7, {"z": 0.2})
    assert not fam.complete
    assert all(p.value > 0.62 for p in fam.points) and fam.points
    assert "no_return" in fam.message
