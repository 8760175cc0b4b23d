"""Poincare sections: the ones a system does not have are refused with the names it has."""

import pytest

from helpers.orbit_systems import impact_oscillator
from legsim.orbits import OrbitError, OrbitProblem, Section


def test_bad_sections_are_rejected_with_messages():
    with pytest.raises(OrbitError, match=r"no transition of that name .* transitions: \['impact'\]"):
        OrbitProblem(impact_oscillator(), Section.after("bounce"), h=1e-2, eps=1e-4)
    with pytest.raises(OrbitError, match="has no coordinate 'zd'"):
        OrbitProblem(impact_oscillator(), Section.level("free", "zd"), h=1e-2, eps=1e-4)
    with pytest.raises(OrbitError, match="unknown mode 'flight'"):
        OrbitProblem(impact_oscillator(), Section.level("flight", "v"), h=1e-2, eps=1e-4)
    with pytest.raises(OrbitError, match="direction must be"):
        Section.level("free", "v", 0.0, 2)
