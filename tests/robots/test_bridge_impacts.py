"""Impacts of the bridge: a bouncing point is the closed-form ball; plastic landings keep the
momentum no impulse acts on."""

import math

import numpy as np
import pinocchio as pin
import pytest
from legsim.robots.bridge import ContactBridge, PointContact, add_point_frame

from helpers.bridge_models import G, ball_model, rod_model
from legsim import simulate


def test_bouncing_point_is_the_closed_form_ball():
    c, z0 = 0.5, 1.0
    model, _ = ball_model()
    bridge = ContactBridge(model, [PointContact("floor", "ball", restitution=c, tangential=False)])
    system = bridge.system("free", [0.0, z0, 0.0, 0.0])
    assert [(tr.name, tr.target) for tr in system.outgoing("free")] == [("bounce_floor", "free")]
    t_zeno = math.sqrt(2 * z0 / G) * (1 + 2 * c / (1 - c))
    eps = 1e-3
    ex = simulate(system, [0.3, z0, 0.0, 0.0], "free", 2 * t_zeno, 1e-3, eps)
    assert ex.status == "finished"
    first = ex.transitions[0]
    assert first.time == pytest.approx(math.sqrt(2 * z0 / G), abs=1e-12)  # free fall: RK4 + Hermite exact
    assert first.state_after[3] == pytest.approx(-c * first.state_before[3], rel=1e-14)
    assert first.state_after[2] == first.state_before[2] == 0.0
    assert min(seg.x[:, 1].min() for seg in ex.segments) >= -eps
    assert len(ex.transitions) < 20_000


def test_a_rod_landing_on_a_frictionless_floor_ends_lying_with_its_weight_shared():
    """Both ends land plastically (c = 0, z only): no horizontal impulse ever acts, so the
    horizontal momentum is kept; at rest on both ends each carries m g / 2 and the energy left
    is the sliding m xd^2 / 2."""
    m, xd = 1.0, 0.5
    model = rod_model(m=m, I=0.1)
    model.gravity = pin.Motion(np.array([0, 0, -G, 0, 0, 0]))
    body = model.getJointId("theta")
    add_point_frame(model, "tail", body, (-0.5, 0, 0))
    bridge = ContactBridge(
        model,
        [PointContact("a", "tip", tangential=False), PointContact("b", "tail", tangential=False)],
        mode_names={(): "air"},
    )
    x0 = [0.0, 1.0, 0.3, xd, 0.0, 0.0]
    system = bridge.system("air", x0)
    ex = simulate(system, x0, "air", 1.5, 1e-3, 1e-3)
    assert [tr.name for tr in ex.transitions] == ["touchdown_a", "touchdown_b"] and ex.final_mode == "a+b"
    x = ex.final_state
    np.testing.assert_allclose(x[3:], [xd, 0.0, 0.0], atol=1e-9)
    forces = bridge.constraint_forces("a+b", x)
    assert forces["a"][0] == pytest.approx(m * G / 2, abs=1e-9) and forces["b"][0] == pytest.approx(m * G / 2, abs=1e-9)
    assert system.energy("a+b", x) == pytest.approx(0.5 * m * xd**2, abs=1e-9)
    # the constraint is kept at the acceleration level; the ends stay on the floor to RK4 accuracy
    assert abs(x[1]) < 1e-9 and abs(x[2]) < 1e-9


#: No friction cones: the plain least-norm solution.
NO_CONES = np.empty((0, 3))


def test_a_singular_support_takes_the_least_norm_impulses_and_an_inconsistent_one_none():
    # A = B B^T with B (4, 3): four rows on three degrees of freedom (two stuck points of one
    # body), rank 3: J = W = B and M = I, so M^-1 W^T = B^T. The solve (the native library's,
    # which its own constrained solves use) gives the pseudo-inverse's solution, as symmetric
    # (least_norm) and as rows whose motion B^T y is unique; it refuses a right-hand side with a
    # part outside A's range, and rows whose null vector moves the body (M^-1 W^T of rank 4).
    from legsim.robots.bridge.impacts import solve_rows

    rng = np.random.default_rng(3)
    B = rng.normal(size=(4, 3))
    A = B @ B.T
    b = A @ rng.normal(size=4)
    refused = b.copy()
    assert not solve_rows(A.copy(), refused, 4, False, np.eye(4), NO_CONES) and np.array_equal(refused, b)
    for least_norm in (True, False):
        y = b.copy()
        assert solve_rows(A.copy(), y, 4, least_norm, B.T.copy(), NO_CONES)
        assert np.allclose(y, np.linalg.pinv(A) @ b, rtol=0.0, atol=1e-10 * np.abs(y).max())
        null = np.linalg.svd(A)[0][:, -1]
        assert not solve_rows(A.copy(), b + 1e-3 * np.abs(b).max() * null, 4, least_norm, B.T.copy(), NO_CONES)
    # a regular system is solved as it is, whichever the flag
    regular = A + np.eye(4)
    for least_norm in (False, True):
        x = b.copy()
        assert solve_rows(regular.copy(), x, 4, least_norm, np.eye(4), NO_CONES)
        assert np.allclose(regular @ x, b, rtol=1e-12, atol=0.0)
    assert not solve_rows(np.full((2, 2), np.nan), np.ones(2), 2, True, np.eye(2), NO_CONES)
