"""Jacobians of the return map (saltation and finite differences) and the multipliers they give."""

import math

import numpy as np
import pytest

from helpers.orbit_systems import hopf_reset, impact_oscillator
from legsim.orbits import (
    OrbitError,
    OrbitProblem,
    Section,
    find_orbit,
    jacobian_fd,
    jacobian_saltation,
    return_map,
    saltation_matrix,
)


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
        prob = OrbitProblem(
            hopf_reset(analytic_derivatives=analytic), Section.after("jump"), h=2e-3, eps=1e-4, t_max=2.0
        )
        J.append(jacobian_saltation(prob, return_map(prob, x)))
    # Forward differences of the field (relative ~1e-8 per stage Jacobian) against the exact
    # Jacobian, guard gradient and reset Jacobian: measured 5.4e-9 over the whole return.
    assert np.max(np.abs(J[0] - J[1])) < 3e-8


def test_saltation_matrix_of_the_wall_impact_in_closed_form():
    # Identity-free check: at q = (0, -V) the guard is x, f- = (-V, a-), f+ = (V+, a+),
    # DR = diag(1, -e). Xi = DR + (f+ - DR f-) e_x^T / (-V).
    sysm = impact_oscillator()
    tr = sysm.transitions[0]
    V, e = 1.7, 0.8
    q = np.array([0.0, -V])
    xp = tr.reset(q)
    f = sysm.mode("free").field
    fm, fp = f(0, q, None), f(0, xp, None)
    DR = np.diag([1.0, -e])
    expect = DR + np.outer(fp - DR @ fm, [1.0, 0.0]) / (-V)
    assert np.max(np.abs(saltation_matrix(sysm, tr, q, xp) - expect)) < 1e-8


@pytest.mark.parametrize("step", [0.0, -1e-6, 0.5, float("nan")])
def test_finite_difference_steps_outside_zero_to_a_tenth_are_rejected(step):
    # A step of 0 would divide by zero; a step of 10 is a chord across the whole map, no
    # derivative (on this oscillator its multiplier is off by a factor 4).
    prob = OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-2, eps=1e-4)
    with pytest.raises(OrbitError, match=r"fd_step must be a relative step in \(0, 0.1\]") as info:
        find_orbit(prob, [0.0, 1.0], jacobian="fd", fd_step=step)
    assert info.value.key == "fd_step"


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
