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


def two_walls(e=0.8, zeta=0.1, omega=2.0, kicks=(1.0, 0.5)):
    """The impact oscillator whose wall hands it over between two copies of its mode, "a" and
    "b", by transitions both named "impact" (a -> b kicks by kicks[0], b -> a by kicks[1])."""
    import numpy as np

    from legsim import HybridSystem, Mode, Transition

    def field(t, x, u):
        return np.array([x[1], -2 * zeta * omega * x[1] - omega**2 * x[0]])

    def wall(source, target, kick):
        return Transition(
            source,
            target,
            guard=lambda x: max(x[0], x[1]),
            reset=lambda x: np.array([x[0], -e * x[1] + kick]),
            name="impact",
        )

    modes = {m: Mode(2, field, names=("x", "v")) for m in ("a", "b")}
    return HybridSystem(modes, [wall("a", "b", kicks[0]), wall("b", "a", kicks[1])], name="two walls")


def test_a_transition_into_several_modes_needs_its_target_named():
    with pytest.raises(OrbitError, match=r"several modes \['a', 'b'\]; name the target mode"):
        OrbitProblem(two_walls(), Section.after("impact"), h=1e-2, eps=1e-4)
    with pytest.raises(OrbitError, match=r"no transition 'impact' leads to mode 'c'; it leads to \['a', 'b'\]"):
        OrbitProblem(two_walls(), Section.after("impact", "c"), h=1e-2, eps=1e-4)


@pytest.mark.parametrize("mode, kick_in, kick_out", [("a", 0.5, 1.0), ("b", 1.0, 0.5)])
def test_a_section_after_a_transition_into_one_mode_returns_after_two_impacts(mode, kick_in, kick_out):
    # From the wall with speed V the oscillator returns with speed rho V (rho = exp(-zeta w pi /
    # w_d)); the wall into the other mode gives e rho V + kick_out, the one back into ``mode``
    # e rho (e rho V + kick_out) + kick_in: V* = (e rho kick_out + kick_in) / (1 - (e rho)^2), the
    # multiplier (e rho)^2.
    import math

    from legsim.orbits import find_orbit

    e, zeta, omega = 0.8, 0.1, 2.0
    rho = math.exp(-zeta * omega * math.pi / (omega * math.sqrt(1 - zeta**2)))
    problem = OrbitProblem(two_walls(), Section.after("impact", mode), h=1e-3, eps=1e-8, t_max=10.0)
    result = find_orbit(problem, {"x": 0.0, "v": 1.0})
    assert result.converged and result.mode == mode and result.transitions == ["impact", "impact"]
    assert result.fixed_point[1] == pytest.approx((e * rho * kick_out + kick_in) / (1 - (e * rho) ** 2), rel=1e-6)
    assert abs(result.multipliers[0]) == pytest.approx((e * rho) ** 2, rel=1e-6)
