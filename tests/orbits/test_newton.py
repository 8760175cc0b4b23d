"""Periodic orbits on small analytic hybrid systems whose return maps are known in closed form.

Systems (defined here):

* impact oscillator: a damped oscillator x'' + 2 zeta w x' + w^2 x = 0 on x >= 0 with a wall at
  x = 0 (restitution e) that also kicks the velocity by D: v+ = -e v- + D. From x = 0 with
  velocity V it returns after pi / w_d with speed V rho, rho = exp(-zeta w pi / w_d), so the
  map V -> e rho V + D is linear: V* = D / (1 - e rho), multiplier e rho, period pi / w_d.
* Hopf oscillator with a reset: r' = mu r (1 - r^2), theta' = w; crossing the positive x axis
  upwards resets r -> kappa r and theta -> -beta. Over the arc time T = beta / w,
  r(T)^2 = 1 / (1 + (r0^-2 - 1) E), E = exp(-2 mu T), so r* ^2 = (kappa^2 - E) / (1 - E) and the
  multiplier is E / kappa^2. Nonlinear field, guard and reset: the saltation test bed.
* hopping ball: free flight z'' = -g, and at the ground a reset zd+ = D - k zd- (an actuated
  bounce whose take-off speed falls with the impact speed). Apex speeds map as v -> D - k v:
  v* = D / (1 + k), apex height v*^2 / 2g, multiplier -k (period doubling at k = 1).
"""

import math

import numpy as np
import pytest

from legsim import HybridSystem, Mode, Transition
from legsim.orbits import (OrbitError, OrbitProblem, Section, continue_family, find_orbit, jacobian_fd,
                           jacobian_saltation, return_map, saltation_matrix)

G = 9.81


# -- systems -------------------------------------------------------------------------------
def impact_oscillator(zeta=0.1, omega=2.0, e=0.8, kick=1.0):
    def field(t, x, u):
        return np.array([x[1], -2 * zeta * omega * x[1] - omega ** 2 * x[0]])

    return HybridSystem(
        {"free": Mode(2, field, names=("x", "v"))},
        [Transition("free", "free", guard=lambda x: max(x[0], x[1]),
                    reset=lambda x: np.array([x[0], -e * x[1] + kick]), name="impact")],
        name="impact oscillator")


def oscillator_closed_form(zeta=0.1, omega=2.0, e=0.8, kick=1.0):
    wd = omega * math.sqrt(1 - zeta ** 2)
    rho = math.exp(-zeta * omega * math.pi / wd)
    v_star = kick / (1 - e * rho)
    # Largest displacement after leaving the wall with speed V: (V / w) exp(-zeta w t_peak).
    t_peak = math.acos(zeta) / wd
    x_max = v_star / omega * math.exp(-zeta * omega * t_peak)
    return {"v": v_star, "multiplier": e * rho, "period": math.pi / wd, "x_max": x_max}


def hopf_reset(mu=1.0, omega=2 * math.pi, kappa=0.9, beta=2.0, analytic_derivatives=False):
    def field(t, x, u):
        r2 = x[0] ** 2 + x[1] ** 2
        return np.array([mu * x[0] * (1 - r2) - omega * x[1], mu * x[1] * (1 - r2) + omega * x[0]])

    def jac(t, x, u):
        r2 = x[0] ** 2 + x[1] ** 2
        return np.array([[mu * (1 - r2) - 2 * mu * x[0] ** 2, -2 * mu * x[0] * x[1] - omega],
                         [-2 * mu * x[0] * x[1] + omega, mu * (1 - r2) - 2 * mu * x[1] ** 2]])

    c, s = math.cos(beta), math.sin(beta)
    rot = np.array([[c, s], [-s, c]])  # rotation by -beta

    def reset(x):
        return kappa * rot @ x

    extra = {}
    if analytic_derivatives:
        extra = {"guard_gradient": lambda x: np.array([0.0, -1.0]), "reset_jacobian": lambda x: kappa * rot}
    return HybridSystem(
        {"arc": Mode(2, field, names=("x", "y"), jacobian=jac if analytic_derivatives else None)},
        [Transition("arc", "arc", guard=lambda x: max(-x[1], -x[0]), reset=reset, name="jump", **extra)],
        name="hopf with reset")


def hopf_closed_form(mu=1.0, omega=2 * math.pi, kappa=0.9, beta=2.0):
    E = math.exp(-2 * mu * beta / omega)
    r_star = math.sqrt((kappa ** 2 - E) / (1 - E))
    return {"r": r_star, "multiplier": E / kappa ** 2, "period": beta / omega}


def hopping_ball(params):
    kick, k = params["kick"], params.get("k", 0.5)
    return HybridSystem(
        {"flight": Mode(2, lambda t, x, u: np.array([x[1], -G]), names=("z", "zd"))},
        [Transition("flight", "flight", guard=lambda x: max(x[0], x[1]),
                    reset=lambda x: np.array([x[0], kick + k * x[1]]), name="bounce")],
        name="hopping ball", energy=lambda mode, x: 0.5 * x[1] ** 2 + G * x[0])


APEX = Section.level("flight", "zd", 0.0, "decreasing")


# -- fixed points against closed forms -------------------------------------------------------
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


@pytest.mark.parametrize("section", [
    Section.level("free", "v", 0.0, -1),
    Section.crossing("free", lambda x: x[1], -1),  # the same section through a function (FD gradient)
])
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


def test_found_orbit_returns_to_itself_under_a_finer_simulation():
    # The residual is the simulation's own; a 4x finer, independent simulation of the found
    # point must return within its accuracy, O(h^4) ~ 1e-8 at h = 1e-2.
    prob = OrbitProblem(hopf_reset(), Section.after("jump"), h=1e-2, eps=1e-4, t_max=2.0)
    res = find_orbit(prob, [-0.3, -0.6], tol=1e-11)
    assert res.converged and res.residual <= 1e-11
    fine = OrbitProblem(hopf_reset(), Section.after("jump"), h=2.5e-3, eps=1e-5, t_max=2.0)
    back = return_map(fine, res.fixed_point)
    assert np.max(np.abs(back.x_end - res.fixed_point)) < 1e-7


def test_free_parameter_gives_the_kick_for_a_prescribed_apex_height():
    # Unknown: the kick D; fixed: the apex height H = 1 m. Closed form D = (1 + k) sqrt(2 g H).
    H, k = 1.0, 0.5
    prob = OrbitProblem(hopping_ball, APEX, h=1e-2, eps=1e-4, t_max=4.0, parameters={"kick": 3.0, "k": k},
                        free=["kick"], fixed=["z"])
    res = find_orbit(prob, {"z": H})
    assert res.converged, res.message
    assert res.fixed_point[0] == H
    # Free flight is a cubic: RK4 and the Hermite crossing are exact to rounding.
    assert abs(res.parameters["kick"] - (1 + k) * math.sqrt(2 * G * H)) < 1e-9
    assert abs(res.multipliers[0] - (-k)) < 1e-6


def test_energy_constraint_picks_the_orbit_of_an_energy_level():
    # Hopping ball with the kick free and the energy fixed: E = g H at the apex.
    H, k = 0.8, 0.5
    prob = OrbitProblem(hopping_ball, APEX, h=1e-2, eps=1e-4, t_max=4.0, parameters={"kick": 3.0, "k": k},
                        free=["kick"], energy=G * H)
    res = find_orbit(prob, {"z": 1.2})
    assert res.converged, res.message
    assert abs(res.fixed_point[0] - H) < 1e-9
    assert abs(res.parameters["kick"] - (1 + k) * math.sqrt(2 * G * H)) < 1e-8


# -- Jacobians --------------------------------------------------------------------------------
@pytest.mark.parametrize("section", [Section.after("jump"), Section.level("arc", "x", 0.0, 1)])
def test_saltation_and_finite_difference_jacobians_agree(section):
    prob = OrbitProblem(hopf_reset(), section, h=2e-3, eps=1e-4, t_max=2.0)
    x = np.array([-0.35, -0.55]) if section.kind == "transition" else np.array([0.0, -0.7])
    ret = return_map(prob, x)
    assert len(ret.transitions) == 1
    J_salt = jacobian_saltation(prob, ret)
    J_fd = jacobian_fd(prob, x)
    # FD at the default step 1e-6 is good to ~1e-9 here; the saltation product with forward-
    # difference field Jacobians to ~5e-9 (measured against analytic derivatives, next test).
    assert np.max(np.abs(J_salt - J_fd)) < 3e-8
    # Both kill the flow direction (a start moved along the flow returns to the same point).
    f = hopf_reset().mode("arc").field(0.0, x, None)
    assert np.max(np.abs(J_salt @ f)) < 1e-8 * np.linalg.norm(f)


def test_analytic_derivatives_give_the_same_saltation_jacobian():
    x = np.array([-0.35, -0.55])
    J = []
    for analytic in (False, True):
        prob = OrbitProblem(hopf_reset(analytic_derivatives=analytic), Section.after("jump"), h=2e-3, eps=1e-4,
                            t_max=2.0)
        J.append(jacobian_saltation(prob, return_map(prob, x)))
    # Forward differences of the field (relative ~1e-8 per stage Jacobian) against the exact
    # Jacobian, guard gradient and reset Jacobian: measured 5.4e-9 over the whole return.
    assert np.max(np.abs(J[0] - J[1])) < 3e-8


def test_saltation_matrix_of_the_wall_impact_in_closed_form():
    # Identity-free check: at q = (0, -V) the guard is x, f- = (-V, a-), f+ = (V+, a+),
    # DR = diag(1, -e). Xi = DR + (f+ - DR f-) e_x^T / (-V).
    sysm = impact_oscillator()
    tr = sysm.transitions[0]
    V, e, kick = 1.7, 0.8, 1.0
    q = np.array([0.0, -V])
    xp = tr.reset(q)
    f = sysm.mode("free").field
    fm, fp = f(0, q, None), f(0, xp, None)
    DR = np.diag([1.0, -e])
    expect = DR + np.outer(fp - DR @ fm, [1.0, 0.0]) / (-V)
    assert np.max(np.abs(saltation_matrix(sysm, tr, q, xp) - expect)) < 1e-8


# -- stability predicts the decay of perturbations -------------------------------------------
def test_largest_multiplier_predicts_the_decay_of_a_perturbation():
    prob = OrbitProblem(hopf_reset(kappa=0.8, beta=3.0), Section.after("jump"), h=2e-3, eps=1e-4, t_max=2.0)
    c, s = math.cos(3.0), math.sin(3.0)
    res = find_orbit(prob, [0.6 * c, -0.6 * s], tol=1e-12)
    assert res.converged
    mu = float(res.multipliers[0].real)
    x = res.fixed_point * (1 + 1e-4)
    dev = [np.linalg.norm(x - res.fixed_point)]
    for _ in range(5):
        x = return_map(prob, x).x_end
        dev.append(np.linalg.norm(x - res.fixed_point))
    measured = (dev[-1] / dev[0]) ** (1 / 5)
    # Linearisation error of a 1e-4 perturbation: relative O(1e-4).
    assert abs(measured - abs(mu)) < 1e-3 * abs(mu)


# -- convergence in h and eps -----------------------------------------------------------------
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


# -- continuation ------------------------------------------------------------------------------
def test_continuation_finds_the_period_doubling_of_the_hopping_ball():
    D = 4.0
    prob = OrbitProblem(hopping_ball, APEX, h=1e-2, eps=1e-4, t_max=4.0, parameters={"kick": D, "k": 0.5})
    fam = continue_family(prob, "k", 0.6, 1.4, 8, {"z": 0.3})
    assert fam.complete, fam.message
    assert [round(p.value, 12) for p in fam.points] == [round(v, 12) for v in np.linspace(0.6, 1.4, 9)]
    for p in fam.points:
        v = D / (1 + p.value)
        assert abs(p.result.fixed_point[0] - v ** 2 / (2 * G)) < 1e-9
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


# -- failures are reported, never answered ------------------------------------------------------
def test_no_return_within_the_time_limit():
    prob = OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-2, eps=1e-4, t_max=1.0)
    res = find_orbit(prob, {"x": 0.0, "v": 1.0})
    assert res.status == "no_return" and not res.converged
    assert "no return to the section after impact within t_max = 1 s" in res.message
    with pytest.raises(OrbitError, match="no_return"):
        res.raise_for_status()


def test_singular_jacobian_of_a_non_isolated_orbit():
    # Undamped, elastic, no kick: every launch speed is periodic (energy is conserved).
    prob = OrbitProblem(impact_oscillator(zeta=0.0, e=1.0, kick=0.0), Section.after("impact"), h=1e-2, eps=1e-4,
                        t_max=5.0)
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


@pytest.mark.parametrize("step", [0.0, -1e-6, 0.5, float("nan")])
def test_finite_difference_steps_outside_zero_to_a_tenth_are_rejected(step):
    # fd_step = 0 divided by zero (an internal SVD error); 10 gave a converged orbit with a
    # multiplier off by a factor 4 (a chord across the whole map, no derivative).
    prob = OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-2, eps=1e-4)
    with pytest.raises(OrbitError, match=r"fd_step must be a relative step in \(0, 0.1\]") as info:
        find_orbit(prob, [0.0, 1.0], jacobian="fd", fd_step=step)
    assert info.value.key == "fd_step"


def test_bad_sections_are_rejected_with_messages():
    with pytest.raises(OrbitError, match=r"no transition of that name .* transitions: \['impact'\]"):
        OrbitProblem(impact_oscillator(), Section.after("bounce"), h=1e-2, eps=1e-4)
    with pytest.raises(OrbitError, match="has no coordinate 'zd'"):
        OrbitProblem(impact_oscillator(), Section.level("free", "zd"), h=1e-2, eps=1e-4)
    with pytest.raises(OrbitError, match="unknown mode 'flight'"):
        OrbitProblem(impact_oscillator(), Section.level("flight", "v"), h=1e-2, eps=1e-4)
    with pytest.raises(OrbitError, match="direction must be"):
        Section.level("free", "v", 0.0, 2)


def test_bad_guess_is_rejected_with_a_message():
    prob = OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-2, eps=1e-4)
    with pytest.raises(OrbitError, match=r"unknown coordinate\(s\) \['q'\]"):
        find_orbit(prob, {"q": 1.0})
    with pytest.raises(OrbitError, match=r"shape \(3,\), expected \(2,\)"):
        find_orbit(prob, [0.0, 1.0, 2.0])


# -- more section and problem features ---------------------------------------------------------
def test_period_two_return_map_squares_the_multiplier():
    # A period-one orbit is a fixed point of P^2 too, with the multiplier squared and twice the
    # period (a period-two gait would be found the same way).
    ref = oscillator_closed_form()
    prob = OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-2, eps=1e-4, t_max=10.0, returns=2)
    res = find_orbit(prob, {"x": 0.0, "v": 1.0})
    assert res.converged, res.message
    assert abs(res.fixed_point[1] - ref["v"]) < 5e-8
    assert abs(res.multipliers[0] - ref["multiplier"] ** 2) < 1e-7
    assert abs(res.period - 2 * ref["period"]) < 1e-7
    assert res.transitions == ["impact", "impact"]


def test_general_constraint_in_place_of_a_fixed_coordinate():
    H, k = 0.6, 0.5
    prob = OrbitProblem(hopping_ball, APEX, h=1e-2, eps=1e-4, t_max=4.0, parameters={"kick": 3.0, "k": k},
                        free=["kick"], constraints=[("apex height", lambda x, p: x[0] - H)])
    res = find_orbit(prob, {"z": 1.0})
    assert res.converged, res.message
    assert abs(res.fixed_point[0] - H) < 1e-12
    assert abs(res.parameters["kick"] - (1 + k) * math.sqrt(2 * G * H)) < 1e-9


def test_a_reset_jumping_across_the_section_is_not_a_crossing():
    # v increases through 0 only at the wall, where the reset jumps from v < 0 to v > 0: with
    # direction +1 the section is never crossed by the flow.
    prob = OrbitProblem(impact_oscillator(), Section.level("free", "v", 0.0, +1), h=1e-2, eps=1e-4, t_max=4.0)
    res = find_orbit(prob, {"x": 0.5, "v": 0.0})
    assert res.status == "no_return", res.message
    # Either direction: the decreasing crossing at the largest displacement counts.
    prob = OrbitProblem(impact_oscillator(), Section.level("free", "v", 0.0, 0), h=1e-2, eps=1e-4, t_max=4.0)
    res = find_orbit(prob, {"x": 0.5, "v": 0.0})
    assert res.converged and abs(res.fixed_point[0] - oscillator_closed_form()["x_max"]) < 5e-8
