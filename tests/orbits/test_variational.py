"""The variational equation along a stored segment: against the flow's exact Jacobian, and the
compiled evaluation against the interpreted one of the same source."""

import numpy as np
import pytest

from legsim import simulate
from legsim.methods import get_method
from legsim.orbits import variational
from legsim.relaxed import driver
from legsim.systems import bouncing_ball
from legsim.systems.oscillator import make_system as oscillator


def sensitivity(system, seg, newton=False, t_stop=None):
    return variational.segment_sensitivity(driver.Evaluator(system, get_method("rk4")), seg, t_stop, newton)


@pytest.fixture(scope="module")
def flight():
    system = bouncing_ball.make_system(restitution=0.9)
    ex = simulate(system, [2.0, 1.0], "flight", 0.5, 1e-2, 1e-6)
    return system, ex.segments[0]


def test_the_free_fall_segment_has_the_exact_flow_jacobian(flight):
    # z'' = -g: d(z, zd)(t) / d(z, zd)(0) = [[1, t], [0, 1]], which RK4's steps reproduce exactly.
    system, seg = flight
    duration = seg.t[-1] - seg.t[0]
    np.testing.assert_allclose(sensitivity(system, seg), [[1.0, duration], [0.0, 1.0]], rtol=0, atol=1e-9)


def test_a_segment_cut_inside_a_step_ends_at_the_cut(flight):
    system, seg = flight
    t_stop = 0.5 * (seg.t[10] + seg.t[11])
    np.testing.assert_allclose(
        sensitivity(system, seg, t_stop=t_stop), [[1.0, t_stop - seg.t[0]], [0.0, 1.0]], rtol=0, atol=1e-9
    )


def test_the_damped_oscillator_matches_its_matrix_exponential():
    # x'' = -2 a x' - w^2 x over the segment: Phi = expm(A T), to RK4's and the differences' accuracy.
    from scipy.linalg import expm

    system = oscillator(omega=2.0, a=0.1, x_max=None)
    ex = simulate(system, [1.0, 0.0], "free", 1.0, 1e-3, 1e-6)
    seg = ex.segments[0]
    A = np.array([[0.0, 1.0], [-4.0, -0.2]])
    exact = expm(A * (seg.t[-1] - seg.t[0]))
    np.testing.assert_allclose(sensitivity(system, seg), exact, rtol=0, atol=1e-8)
    # Newton's Jacobian (forward differences, interpolated where the field Jacobian is constant):
    # ~1e-6 relative is all a Newton step needs.
    assert np.max(np.abs(sensitivity(system, seg, newton=True) - exact)) < 1e-5


def test_compiled_and_interpreted_evaluations_agree_to_the_bit(flight, monkeypatch):
    system, seg = flight
    compiled = sensitivity(system, seg)
    monkeypatch.setattr(driver, "KERNEL", None)
    assert np.array_equal(sensitivity(system, seg), compiled)
