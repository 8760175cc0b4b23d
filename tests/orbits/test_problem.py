"""Orbit problems: settings, unknowns and guesses are checked when the problem is made."""

import pytest

from legsim.orbits import OrbitError, OrbitProblem, Section, find_orbit

from helpers.orbit_systems import impact_oscillator


@pytest.mark.parametrize("kwargs, message", [
    ({"fixed": ["w"]}, r"fixed coordinate\(s\) \['w'\] are not coordinates of mode 'free'"),
    ({"h": -1.0}, "h must be a finite number > 0"),
    ({"free": ["kick"]}, r"free parameter\(s\) \['kick'\] need initial values"),
    ({"fixed": ["x", "v"]}, "nothing to solve for"),
    ({"min_transitions": 0}, "needs min_time > 0"),
    # The oscillator's section has 2 - 1 = 1 multiplier: leaving it out leaves no verdict.
    ({"trivial_multipliers": 1}, "leaves at least one of the section's 1 multiplier"),
    ({"h": 1e-9, "t_max": 100.0}, r"1e\+11 steps per return, more than the limit 1e\+07"),
])
def test_bad_problems_are_rejected_with_messages(kwargs, message):
    base = dict(system=impact_oscillator(), section=Section.level("free", "v", 0.0, -1), h=1e-2, eps=1e-4)
    base.update(kwargs)
    with pytest.raises(OrbitError, match=message):
        OrbitProblem(**base)


def test_bad_guess_is_rejected_with_a_message():
    prob = OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-2, eps=1e-4)
    with pytest.raises(OrbitError, match=r"unknown coordinate\(s\) \['q'\]"):
        find_orbit(prob, {"q": 1.0})
    with pytest.raises(OrbitError, match=r"shape \(3,\), expected \(2,\)"):
        find_orbit(prob, [0.0, 1.0, 2.0])
