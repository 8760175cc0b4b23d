"""Gaits of the passive walkers (robots built with the Pinocchio bridge) against closed forms,
an independent high-accuracy computation and the literature.

Compass gait reference: the gait computed independently of Pinocchio and of legsim, with the
equations of motion of the three point masses written out by hand and scipy's DOP853 and fsolve
(``helpers.compass_gait_reference``).

Literature. For the standard parameters (m = 5, m_H = 10, a = b = 0.5, slope 3 deg) the stable
period-one gait of Goswami, Thuilot & Espiau (INRIA RR-2996, 1996; Int. J. Robotics Research
17(12), 1998) is commonly quoted, just after heel strike in their convention (angles from the
vertical, positive backwards; [theta_ns, theta_s, dtheta_ns, dtheta_s]), as
[0.2187, -0.3234, -0.3772, -1.0918] (rad, rad/s). We recall these numbers rather than read them
from the paper here; they are reproduced to all four digits with g = 9.8 m/s^2 (the velocities
scale with sqrt(g); at g = 9.81 they would read -0.3774 and -1.0924), which we take as the
value the quotation used. The test checks them at g = 9.8, and everything else against the
independent computation.
"""

import math

import numpy as np
import pytest
from legsim.robots import compass_gait, rimless_wheel

from helpers.compass_gait_reference import STANDARD, PointMassCompassGait
from legsim.orbits import OrbitError, OrbitProblem, Section, find_orbit, jacobian_fd, jacobian_saltation, return_map


@pytest.fixture(scope="module")
def reference():
    ref = PointMassCompassGait(**STANDARD).gait()
    assert ref["residual"] < 1e-11
    return ref


def compass_problem(params=None, h=2e-3, eps=1e-6, **integrator):
    model = compass_gait.make(params or {})
    return OrbitProblem(
        model.system, Section.after("heel_strike"), h=h, eps=eps, t_max=3.0, cyclic=["foot_x"], **integrator
    ), model


def leans(x):
    """(theta1, theta2, w1, w2) of the reference from the robot's (stance, hip, rates)."""
    return np.array([x[0], x[0] + x[1], x[2], x[2] + x[3]])


GUESS = [-0.27, 0.54, 1.09, -0.72, 0.0]


@pytest.fixture(scope="module")
def gait():
    prob, model = compass_problem()
    res = find_orbit(prob, GUESS, tol=1e-11)
    assert res.converged, res.message
    return prob, model, res


def test_compass_gait_matches_the_independent_computation(gait, reference):
    _prob, _model, res = gait
    # RK4 at h = 2e-3 (errors ~1e-10 here) against DOP853 at 1e-12.
    assert np.max(np.abs(leans(res.fixed_point) - reference["x"])) < 1e-8
    assert abs(res.period - reference["period"]) < 1e-8
    assert abs(res.step_length - reference["step"]) < 1e-8
    mu, ref_mu = res.multipliers, reference["multipliers"]
    assert len(mu) == 3  # 5 coordinates, minus the flow direction, minus the cyclic foot_x
    # The reference multipliers come from central differences at 1e-6 (~1e-7 accurate).
    assert np.max(np.abs(np.sort_complex(mu) - np.sort_complex(ref_mu))) < 1e-6
    assert res.stable and 0.5 < res.spectral_radius < 0.65
    assert res.transitions == ["heel_strike"]


def test_compass_gait_reproduces_the_quoted_literature_gait():
    # Just after heel strike the new stance leg leans back from the true vertical and the new
    # swing leg (the trailing one) forward; both turn forward. The quotation's four numbers are
    # matched quantity by quantity: angles from the true vertical 0.2187 (stance, behind) and
    # 0.3234 (swing, ahead), rates 1.0918 (stance) and 0.3772 (swing). We do not rely on the
    # order and signs of the quoted vector, which we cannot recall reliably; the independent
    # computation above is the test's real reference.
    prob, _ = compass_problem({"g": 9.8})
    res = find_orbit(prob, GUESS, tol=1e-11)
    assert res.converged
    stance, hip, stanced, hipd, _ = res.fixed_point
    slope = math.radians(3.0)
    # Leans from the true vertical (positive forward): the slope normal leans forward by the slope.
    stance_vertical, swing_vertical = stance + slope, stance + hip + slope
    got = np.array([-stance_vertical, swing_vertical, stanced, stanced + hipd])
    quoted = np.array([0.2187, 0.3234, 1.0918, 0.3772])
    assert np.max(np.abs(got - quoted)) <= 0.5e-4  # the quotation's rounding


def test_swing_foot_scuffs_mid_stance_without_a_heel_strike(gait):
    # Along the gait the swing foot dips below the slope behind the stance foot (the model has
    # no knees); the guard must wait for it to be in front and descending: one strike per step.
    prob, model, res = gait
    cg = model.info["compass_gait"]
    ex = return_map(prob, res.fixed_point).execution
    seg = ex.segments[0]
    feet = np.array([cg.swing_foot(x)[0] for x in seg.x])
    below = feet[:, 1] < -1e-4
    assert below.any() and np.all(feet[below, 0] < 0.0)
    assert feet[:, 1].min() < -3e-3
    strikes = [tr for tr in ex.transitions if tr.time <= res.return_time + 1e-9]
    assert [tr.name for tr in strikes] == ["heel_strike"]


def test_a_tolerance_below_the_return_maps_noise_stalls_with_a_message(gait):
    prob, _, res = gait
    stalled = find_orbit(prob, res.fixed_point, tol=1e-20, max_iterations=12)
    assert stalled.status == "stalled" and not stalled.converged
    assert "stalls at" in stalled.message and "raise tol" in stalled.message
    assert stalled.residual < 1e-13  # the residual it did reach is at rounding level


def test_compass_gait_saltation_and_finite_difference_jacobians_agree(gait):
    prob, _, res = gait
    ret = return_map(prob, res.fixed_point)
    J_salt = jacobian_saltation(prob, ret)
    J_fd = jacobian_fd(prob, res.fixed_point)
    assert np.max(np.abs(J_salt - J_fd)) < 1e-6 * max(1.0, np.max(np.abs(J_salt)))


def test_largest_multiplier_predicts_the_decay_of_a_perturbation(gait):
    # Follow a perturbation over several steps and read its component along the dominant
    # (complex) eigenvector with the left eigenvectors of the restricted Jacobian: in the linear
    # regime that component is multiplied by the leading multiplier at every step, in modulus
    # and in phase.
    prob, _, res = gait
    D = res.jacobian[:4, :4]
    evals, right = np.linalg.eig(D)
    left = np.linalg.inv(right)
    lead = int(np.argmax(np.abs(evals)))
    assert abs(evals[lead] - res.multipliers[0]) < 1e-8 or abs(evals[lead] - res.multipliers[1]) < 1e-8
    x = res.fixed_point.copy()
    x[:4] += 1e-6 * np.array([1.0, -0.5, 0.8, 0.3])
    comps = []
    for _ in range(5):
        comps.append(left[lead] @ (x[:4] - res.fixed_point[:4]))
        x = return_map(prob, x).x_end
    ratios = np.array(comps[1:]) / np.array(comps[:-1])
    # What is left is the nonlinear part of the step map: it grows in proportion to the
    # perturbation (measured 1.2e-4 relative at 1e-6, 1.2e-3 at 1e-5, 1.2e-2 at 1e-4).
    assert np.max(np.abs(ratios - evals[lead])) < 3e-4 * abs(evals[lead])
    decay = abs(comps[-1] / comps[0]) ** 0.25
    assert abs(decay - res.spectral_radius) < 3e-5


def test_compass_gait_converges_at_order_four(reference):
    hs = [8e-3, 4e-3, 2e-3]
    errs = []
    for h in hs:
        prob, _ = compass_problem(h=h, eps=1e-8)
        res = find_orbit(prob, GUESS, tol=1e-12)
        assert res.converged
        errs.append(max(np.max(np.abs(leans(res.fixed_point) - reference["x"])), abs(res.period - reference["period"])))
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert 3.5 < slope < 4.5, (slope, errs)


def test_error_controlled_search_reaches_the_reference_gait_and_follows_the_tolerance(reference):
    # dopri5 with h = 0.1 s as the largest step: with fixed steps of 0.1 s the "gait" is 2e-5
    # off (measured 2.0e-5), under error control the fixed point's error follows rtol (measured
    # 6.0e-7, 5.5e-9 and 5.0e-11 at rtol 1e-6, 1e-8, 1e-10) down to the reference's own 1e-12.
    def error(**tolerances):
        prob, _ = compass_problem(h=0.1, method="dopri5", **tolerances)
        res = find_orbit(prob, GUESS, tol=1e-12)
        assert res.converged, res.message
        return max(np.max(np.abs(leans(res.fixed_point) - reference["x"])), abs(res.period - reference["period"]))

    assert error() > 1e-6
    rtols = [1e-6, 1e-8, 1e-10]
    errs = [error(rtol=rtol) for rtol in rtols]
    assert errs[-1] < 1e-9
    slope = np.polyfit(np.log(rtols), np.log(errs), 1)[0]
    assert 0.8 < slope < 1.2, (slope, errs)


def test_the_return_map_lands_and_halves_as_the_problem_says():
    # At eps = 1e-6 a step of ~0.02 s reaches the heel-strike strip only after a dozen halvings
    # (0.02 / 2^14 ~ 1e-6); aimed and dense landings need none. A budget of 2 halvings therefore
    # ends a halving return, and not a dense one.
    def first_return(landing, max_halvings):
        prob, _ = compass_problem(h=0.1, method="dopri5", rtol=1e-10, landing=landing, max_halvings=max_halvings)
        return return_map(prob, GUESS)

    assert first_return("halve", 64).execution.counters["halvings"] >= 12
    assert first_return("dense", 2).execution.counters["halvings"] <= 2
    with pytest.raises(OrbitError, match="halving_exhausted"):
        first_return("halve", 2)


# -- rimless wheel: closed forms --------------------------------------------------------------------
def rimless_closed_form(m, I, l, spokes, g, slope):  # noqa: E741 (the model's parameter names: called with **params)
    alpha, gamma = math.pi / spokes, math.radians(slope)
    c = (I + m * l * l * math.cos(2 * alpha)) / (I + m * l * l)
    K = 4 * m * g * l * math.sin(alpha) * math.sin(gamma) / (I + m * l * l)
    w = math.sqrt(c * c * K / (1 - c * c))
    # Period: time from psi = gamma - alpha to gamma + alpha (psi from the true vertical),
    # dt = dpsi / omega(psi), omega^2 = w^2 + 2 m g l (cos(gamma - alpha) - cos psi) / (I + m l^2).
    from scipy.integrate import quad

    k = 2 * m * g * l / (I + m * l * l)
    period, _ = quad(
        lambda p: 1 / math.sqrt(w * w + k * (math.cos(gamma - alpha) - math.cos(p))),
        gamma - alpha,
        gamma + alpha,
        epsabs=1e-14,
        epsrel=1e-13,
    )
    return {
        "alpha": alpha,
        "c": c,
        "K": K,
        "omega": w,
        "multiplier": c * c,
        "step": 2 * l * math.sin(alpha),
        "period": period,
    }


RIMLESS_CASES = [
    {"m": 1.0, "I": 0.0, "l": 1.0, "spokes": 10, "g": 9.81, "slope": 5.0},  # McGeer's point-mass wheel
    {"m": 2.0, "I": 0.3, "l": 0.8, "spokes": 8, "g": 9.81, "slope": 8.0},  # with hub inertia (Coleman et al.)
]


@pytest.mark.parametrize("params", RIMLESS_CASES)
def test_rimless_wheel_fixed_point_and_contraction_match_closed_forms(params):
    ref = rimless_closed_form(**params)
    model = rimless_wheel.make(params)
    prob = OrbitProblem(model.system, Section.after("impact"), h=2e-3, eps=1e-6, t_max=3.0, cyclic=["foot_x"])
    res = find_orbit(prob, [-ref["alpha"], 1.0, 0.0], tol=1e-12)
    assert res.converged, res.message
    assert abs(res.fixed_point[0] + ref["alpha"]) < 1e-12
    assert abs(res.fixed_point[1] - ref["omega"]) < 1e-9
    assert abs(res.multipliers[0] - ref["multiplier"]) < 1e-8
    assert abs(res.step_length - ref["step"]) < 1e-12
    assert abs(res.period - ref["period"]) < 1e-9


def test_rimless_wheel_step_map_is_the_closed_form_map_away_from_the_fixed_point():
    params = RIMLESS_CASES[1]
    ref = rimless_closed_form(**params)
    model = rimless_wheel.make(params)
    prob = OrbitProblem(model.system, Section.after("impact"), h=2e-3, eps=1e-6, t_max=3.0, cyclic=["foot_x"])
    for w in (0.8, 1.5, 3.0):
        w_next = return_map(prob, [-ref["alpha"], w, 0.0]).x_end[1]
        assert abs(w_next - ref["c"] * math.sqrt(w * w + ref["K"])) < 1e-9


def test_rimless_wheel_too_slow_to_vault_comes_to_rest_and_no_orbit_is_reported():
    params = RIMLESS_CASES[0]
    ref = rimless_closed_form(**params)
    model = rimless_wheel.make(params)
    # Vaulting over psi = 0 needs w^2 > 2 g / l (1 - cos(alpha - gamma)) = 0.503 (rad/s)^2: at
    # w = 0.5 the wheel rocks back onto the trailing spoke, rolls forward onto the next one and
    # loses speed at every impact: the motion dies out, there is no periodic orbit near here.
    prob = OrbitProblem(
        model.system, Section.after("impact"), h=2e-3, eps=1e-6, t_max=2.0, cyclic=["foot_x"], max_transitions=200
    )
    first = return_map(prob, [-ref["alpha"], 0.5, 0.0])
    assert [tr.name for tr in first.transitions] == ["back_impact", "impact"]
    # Each swing returns to the impact angle with the speed it left with (energy is conserved
    # between impacts), and each impact multiplies the speed by c: c^2 * 0.5 after two.
    assert abs(first.x_end[1] - ref["c"] ** 2 * 0.5) < 1e-9
    res = find_orbit(prob, [-ref["alpha"], 0.5, 0.0])
    assert not res.converged and res.multipliers is None
    # Newton's method drives w towards rest, where the map is not resolved (its noise is 5.7e-6
    # under 1e-11 probes, above the residual's 7.7e-7): the search ends map_unresolved rather
    # than diverged; either way no orbit.
    assert res.status in ("diverged", "no_return", "max_iterations", "map_unresolved"), res.message
    # Too short a time limit gives the no-return report instead.
    short = OrbitProblem(model.system, Section.after("impact"), h=2e-3, eps=1e-6, t_max=0.2, cyclic=["foot_x"])
    res = find_orbit(short, [-ref["alpha"], 0.5, 0.0])
    assert res.status == "no_return" and "within t_max = 0.2 s" in res.message


def test_a_walker_that_falls_is_a_failure_not_a_gait():
    # Thrown backwards (stance rate -5 rad/s) the walker tips over its stance foot: once the hip
    # is below the slope the run ends (model_breakdown), and no orbit is reported (rather than
    # legs swinging on under the ground like a pendulum, where Newton would find a "family").
    prob, _ = compass_problem()
    res = find_orbit(prob, [-0.27, 0.54, -5.0, -0.72, 0.0])
    assert res.status == "simulation_failed" and res.multipliers is None
    assert "model_breakdown" in res.message and "the hip is below the slope: the walker fell" in res.message
    # The hip height l cos(stance) reaches 0 at stance = -pi/2: where the run stopped (its time
    # is in the message; the heel strike's guard is nan past it).
