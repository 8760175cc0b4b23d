"""find_orbit on the analytic systems of helpers.orbit_systems: fixed points, periods and
multipliers against closed forms, free parameters and constraints, convergence in h and eps,
and failures reported as such."""

import math

import numpy as np
import pytest

from helpers.orbit_systems import (
    APEX,
    G,
    hopf_closed_form,
    hopf_reset,
    hopping_ball,
    impact_oscillator,
    oscillator_closed_form,
)
from legsim.orbits import OrbitProblem, Section, find_orbit
from legsim.orbits import newton as newton_module


def test_impact_oscillator_after_transition_matches_closed_form():
    ref = oscillator_closed_form()
    prob = OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-2, eps=1e-4, t_max=5.0)
    res = find_orbit(prob, {"x": 0.0, "v": 1.0})
    assert res.converged, res.message
    # RK4 at h = 1e-2: errors of order h^4 = 1e-8.
    assert abs(res.fixed_point[1] - ref["v"]) < 5e-8
    assert abs(res.fixed_point[0]) < 1e-12  # the reset image lies on the wall
    assert abs(res.period - ref["period"]) < 5e-8
    assert res.multipliers.shape == (1,)
    assert abs(res.multipliers[0] - ref["multiplier"]) < 1e-7
    assert res.stable and res.transitions == ["impact"]
    # The relaxed return time adds the strip hold, between 0 and eps + h here (|dg/dt| ~ 1).
    assert 0.0 <= res.return_time - res.period <= prob.eps + prob.h


@pytest.mark.parametrize(
    "section",
    [
        Section.level("free", "v", 0.0, -1),
        Section.crossing("free", lambda x: x[1], -1),  # the same section through a function (FD gradient)
    ],
)
def test_impact_oscillator_crossing_section_matches_closed_form(section):
    ref = oscillator_closed_form()
    prob = OrbitProblem(impact_oscillator(), section, h=1e-2, eps=1e-4, t_max=5.0)
    res = find_orbit(prob, {"x": 0.5, "v": 0.0})
    assert res.converged, res.message
    assert abs(res.fixed_point[0] - ref["x_max"]) < 5e-8
    assert abs(res.fixed_point[1]) < 1e-9
    assert abs(res.multipliers[0] - ref["multiplier"]) < 1e-7
    assert abs(res.period - ref["period"]) < 5e-8


def test_hopf_reset_fixed_point_and_multiplier():
    ref = hopf_closed_form()
    prob = OrbitProblem(hopf_reset(), Section.after("jump"), h=2e-3, eps=1e-4, t_max=2.0)
    c, s = math.cos(2.0), math.sin(2.0)
    res = find_orbit(prob, [0.7 * c, -0.7 * s])
    assert res.converged, res.message
    r = float(np.hypot(*res.fixed_point))
    assert abs(r - ref["r"]) < 1e-9
    # The reset image lies on the ray at angle -beta.
    assert abs(math.atan2(res.fixed_point[1], res.fixed_point[0]) + 2.0) < 1e-9
    assert abs(res.multipliers[0] - ref["multiplier"]) < 1e-7
    assert abs(res.period - ref["period"]) < 1e-9


def test_free_parameter_gives_the_kick_for_a_prescribed_apex_height():
    # Unknown: the kick D; fixed: the apex height H = 1 m. Closed form D = (1 + k) sqrt(2 g H).
    H, k = 1.0, 0.5
    prob = OrbitProblem(
        hopping_ball, APEX, h=1e-2, eps=1e-4, t_max=4.0, parameters={"kick": 3.0, "k": k}, free=["kick"], fixed=["z"]
    )
    res = find_orbit(prob, {"z": H})
    assert res.converged, res.message
    assert res.fixed_point[0] == H
    # Free flight is a cubic: RK4 and the Hermite crossing are exact to rounding.
    assert abs(res.parameters["kick"] - (1 + k) * math.sqrt(2 * G * H)) < 1e-9
    assert abs(res.multipliers[0] - (-k)) < 1e-6


def test_energy_constraint_picks_the_orbit_of_an_energy_level():
    # Hopping ball with the kick free and the energy fixed: E = g H at the apex.
    H, k = 0.8, 0.5
    prob = OrbitProblem(
        hopping_ball, APEX, h=1e-2, eps=1e-4, t_max=4.0, parameters={"kick": 3.0, "k": k}, free=["kick"], energy=G * H
    )
    res = find_orbit(prob, {"z": 1.2})
    assert res.converged, res.message
    assert abs(res.fixed_point[0] - H) < 1e-9
    assert abs(res.parameters["kick"] - (1 + k) * math.sqrt(2 * G * H)) < 1e-8


def test_general_constraint_in_place_of_a_fixed_coordinate():
    H, k = 0.6, 0.5
    prob = OrbitProblem(
        hopping_ball,
        APEX,
        h=1e-2,
        eps=1e-4,
        t_max=4.0,
        parameters={"kick": 3.0, "k": k},
        free=["kick"],
        constraints=[("apex height", lambda x, p: x[0] - H)],
    )
    res = find_orbit(prob, {"z": 1.0})
    assert res.converged, res.message
    assert abs(res.fixed_point[0] - H) < 1e-12
    assert abs(res.parameters["kick"] - (1 + k) * math.sqrt(2 * G * H)) < 1e-9


def test_fixed_point_converges_at_order_four_in_h_and_does_not_degrade_with_eps():
    ref = oscillator_closed_form()
    hs = [0.08, 0.04, 0.02, 0.01]
    errs = []
    for h in hs:
        prob = OrbitProblem(impact_oscillator(), Section.after("impact"), h=h, eps=1e-6, t_max=5.0)
        res = find_orbit(prob, {"x": 0.0, "v": 2.0}, tol=1e-13)
        assert res.converged, res.message
        errs.append(max(abs(res.fixed_point[1] - ref["v"]), abs(res.period - ref["period"])))
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert 3.6 < slope < 4.4, (slope, errs)
    # eps only sets how long the state is held at the guard point, not where the flow resumes:
    # the fixed point at h = 0.01 stays within the O(h^4) error for eps from 1e-2 to 1e-7, far
    # inside the O(eps) + O(h^4) bound.
    for eps in (1e-2, 1e-4, 1e-7):
        prob = OrbitProblem(impact_oscillator(), Section.after("impact"), h=0.01, eps=eps, t_max=5.0)
        res = find_orbit(prob, {"x": 0.0, "v": 2.0}, tol=1e-13)
        assert abs(res.fixed_point[1] - ref["v"]) <= 2 * errs[-1]
        # The relaxed return time is the period plus the hold, O(eps) + O(h).
        assert abs(res.return_time - ref["period"]) <= eps + 0.01 + 2 * errs[-1]


def test_singular_jacobian_of_a_non_isolated_orbit():
    # Undamped, elastic, no kick: every launch speed is periodic (energy is conserved).
    prob = OrbitProblem(
        impact_oscillator(zeta=0.0, e=1.0, kick=0.0), Section.after("impact"), h=1e-2, eps=1e-4, t_max=5.0
    )
    res = find_orbit(prob, {"x": 0.0, "v": 1.0}, tol=1e-14)
    assert res.status == "singular_jacobian", res.message
    assert "not isolated" in res.message and "v" in res.message


def test_divergence_when_there_is_no_orbit():
    # zd+ = 1 + 1.2 |zd-|: every bounce gains speed, v -> 1.2 v + 1 has no fixed point with v > 0.
    # (With a negative kick, v -> 1.5 v - 1, Newton rightly finds the unstable orbit v* = 2.)
    prob = OrbitProblem(hopping_ball, APEX, h=1e-2, eps=1e-4, t_max=4.0, parameters={"kick": 1.0, "k": -1.2})
    res = find_orbit(prob, {"z": 1.0})
    assert res.status == "diverged", res.message
    assert "no Newton step" in res.message and "no periodic orbit" in res.message
    assert not res.converged and res.multipliers is None
    # The map is smooth: what it resolves there is far below the residual, and the search says so.
    acc = res.map_accuracy
    assert acc is not None and acc.resolved < 1e-3 * res.residual
    assert "below the residual, so the map's noise does not explain it" in res.message


def test_a_newton_jacobians_error_does_not_hide_a_singular_jacobian(monkeypatch):
    # Inside the iterations the saltation Jacobian may carry ~1e-6 relative error (the cheaper
    # ``newton=True`` Jacobian); singularity must still be decided on the accurate one.
    accurate = newton_module.jacobian_saltation

    def noisy(problem, ret, newton=False):
        J = accurate(problem, ret)
        return J + 1e-6 * np.max(np.abs(J)) * np.array([[0.3, -0.7], [0.9, 0.4]]) if newton else J

    monkeypatch.setattr(newton_module, "jacobian_saltation", noisy)
    prob = OrbitProblem(
        impact_oscillator(zeta=0.0, e=1.0, kick=0.0), Section.after("impact"), h=1e-2, eps=1e-4, t_max=5.0
    )
    res = find_orbit(prob, {"x": 0.0, "v": 1.0}, tol=1e-14)
    assert res.status == "singular_jacobian", res.message
