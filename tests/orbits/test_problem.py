"""Orbit problems: settings, unknowns and guesses are checked when the problem is made."""

import pytest

from helpers.orbit_systems import impact_oscillator
from legsim.orbits import OrbitError, OrbitProblem, Section, find_orbit


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"fixed": ["w"]}, r"fixed coordinate\(s\) \['w'\] are not coordinates of mode 'free'"),
        ({"h": -1.0}, "h must be a finite number > 0"),
        ({"free": ["kick"]}, r"free parameter\(s\) \['kick'\] need initial values"),
        ({"fixed": ["x", "v"]}, "nothing to solve for"),
        ({"min_transitions": 0}, "needs min_time > 0"),
        # The oscillator's section has 2 - 1 = 1 multiplier: leaving it out leaves no verdict.
        ({"trivial_multipliers": 1}, "leaves at least one of the section's 1 multiplier"),
        ({"h": 1e-9, "t_max": 100.0}, r"1e\+11 steps per return, more than the limit 1e\+07"),
        # Integrator settings that simulate would refuse at the first return are refused up front.
        ({"method": "rk4", "rtol": 1e-8}, r"rtol/atol need a method with an embedded error estimate .* got 'rk4'"),
        ({"method": "rk2", "atol": 1e-8}, r"rtol/atol need a method with an embedded error estimate .* got 'rk2'"),
        ({"method": "rk4", "landing": "dense"}, r"landing 'dense' needs a method with a continuous extension"),
        ({"landing": "bisect"}, r"landing must be one of 'halve', 'aim', 'dense', got 'bisect'"),
        ({"max_halvings": 0}, r"max_halvings must be an integer >= 1, got 0"),
        # Name lists: each name once, none both fixed and cyclic, the section's coordinate not
        # cyclic, and enough coordinates left for a multiplier (2 - 1 - 1 = 0 here).
        ({"fixed": ["x", "x"]}, r"fixed lists \['x'\] more than once"),
        (
            {"system": lambda params: impact_oscillator(), "free": ["k", "k"], "parameters": {"k": 1.0}},
            r"free lists \['k'\] more than once",
        ),
        ({"fixed": ["x"], "cyclic": ["x"]}, r"\['x'\] are both fixed and cyclic"),
        ({"cyclic": ["v"]}, r"'v' is the section's coordinate, held at its value on the section, so it cannot be"),
        ({"cyclic": ["x"]}, r"cyclic = \['x'\] leaves none of the section's multipliers"),
    ],
)
def test_bad_problems_are_rejected_with_messages(kwargs, message):
    base = dict(system=impact_oscillator(), section=Section.level("free", "v", 0.0, -1), h=1e-2, eps=1e-4)
    base.update(kwargs)
    with pytest.raises(OrbitError, match=message):
        OrbitProblem(**base)


@pytest.mark.parametrize(
    "kwargs, key",
    [
        ({"method": "rk4", "rtol": 1e-8}, "rtol"),
        ({"method": "euler", "atol": 1e-8}, "atol"),
        ({"method": "heun", "landing": "dense"}, "landing"),
        ({"max_halvings": -3}, "max_halvings"),
        ({"cyclic": ["x", "x"]}, "cyclic"),
        ({"fixed": ["x"], "cyclic": ["x"]}, "fixed"),
        # A return after a transition counts no crossings: the counts would be ignored.
        ({"min_transitions": 3}, "min_transitions"),
        ({"min_time": 100.0}, "min_time"),
    ],
)
def test_refused_integrator_settings_carry_their_key(kwargs, key):
    # The scene reader names the [integrator] field by this key.
    with pytest.raises(OrbitError) as info:
        OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-2, eps=1e-4, **kwargs)
    assert info.value.key == key


def test_integrator_settings_report_the_tolerances_simulate_uses():
    fixed = OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-2, eps=1e-4)
    assert fixed.integrator_settings == {
        "method": "rk4",
        "h": 1e-2,
        "eps": 1e-4,
        "rtol": None,
        "atol": None,
        "landing": "halve",
        "max_halvings": 64,
    }
    assert fixed.integrator_label == "rk4, h = 0.01 s, eps = 0.0001, landing 'halve'"
    # One tolerance given alone sets the other to a thousandth of it (legsim.simulate's rule).
    controlled = OrbitProblem(
        impact_oscillator(),
        Section.after("impact"),
        h=0.1,
        eps=1e-4,
        method="dopri5",
        rtol=1e-9,
        landing="dense",
        max_halvings=10,
    )
    assert controlled.integrator_settings == {
        "method": "dopri5",
        "h": 0.1,
        "eps": 1e-4,
        "rtol": 1e-9,
        "atol": pytest.approx(1e-12, rel=1e-15),
        "landing": "dense",
        "max_halvings": 10,
    }
    assert controlled.integrator_label == (
        "dopri5, rtol = 1e-09, atol = 1e-12, largest step h = 0.1 s, eps = 0.0001, landing 'dense'"
    )


def test_bad_guess_is_rejected_with_a_message():
    prob = OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-2, eps=1e-4)
    with pytest.raises(OrbitError, match=r"unknown coordinate\(s\) \['q'\]"):
        find_orbit(prob, {"q": 1.0})
    with pytest.raises(OrbitError, match=r"shape \(3,\), expected \(2,\)"):
        find_orbit(prob, [0.0, 1.0, 2.0])
