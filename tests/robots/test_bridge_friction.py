"""Coulomb friction at point contacts (robots/bridge/friction.py, impacts.py) against closed forms: a block
on a slope (stick/slip threshold at tan(theta) = mu, slide distance and time), the slip onset
under a growing push, a rod falling from upright until its foot slips, impacts with the friction
cone (Pinocchio's impulse dynamics inside it, Newton's laws for a sliding impact), and impacts
never adding kinetic energy, the Painleve paradox resolved by a tangential impulse."""

import math

import numpy as np
import pinocchio as pin
import pytest
from legsim.robots.bridge import ContactBridge, PointContact, add_point_frame, planar_floating_base
from legsim.robots.bridge.friction import frictional_impact, mode_change
from legsim.robots.bridge.impacts import SLIDE, STICK, solve_rows
from legsim.robots.bridge.layout import S_ACTIVE
from scipy.optimize import brentq

from legsim import simulate
from legsim.errors import ModelError

G = 9.81
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def block(theta: float, mu: float, m: float = 2.0, actuated: tuple[str, ...] = ()) -> ContactBridge:
    """A point mass m (kg) on a slope of angle theta (rad), descending towards +x: the ground is
    z = 0 and gravity is tilted by theta; its contact "foot" has friction mu."""
    model = pin.Model()
    jx = model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
    jz = model.addJoint(jx, pin.JointModelPZ(), pin.SE3.Identity(), "z")
    model.appendBodyToJoint(jz, pin.Inertia(m, np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity())
    add_point_frame(model, "foot", jz, (0, 0, 0))
    model.gravity = pin.Motion(np.array([G * math.sin(theta), 0, -G * math.cos(theta), 0, 0, 0]))
    return ContactBridge(model, [PointContact("foot", "foot", friction=mu)], mode_names={(): "air"}, actuated=actuated)


def rod(mu: float, m: float = 1.0, length: float = 1.0, restitution: float = 0.0) -> ContactBridge:
    """A uniform rod (inertia m L^2 / 12) on the planar floating base, upright at theta = 0, its
    lower end "foot" a contact with friction mu (theta > 0 leans the top towards +x)."""
    model = pin.Model()
    body = planar_floating_base(model)
    inertia = m * length**2 / 12
    model.appendBodyToJoint(body, pin.Inertia(m, np.zeros(3), np.diag([inertia] * 3)), pin.SE3.Identity())
    add_point_frame(model, "foot", body, (0, 0, -length / 2))
    model.gravity = pin.Motion(np.array([0, 0, -G, 0, 0, 0]))
    return ContactBridge(
        model, [PointContact("foot", "foot", restitution=restitution, friction=mu)], mode_names={(): "air"}
    )


def foot_impact(bridge: ContactBridge, q, v, c: float = 0.0):
    """The frictional impact of the foot alone (stuck to begin with, restitution c) at (q, v):
    (whether it has an outcome, the foot's status and slide direction after it, v+, the foot's
    post-impact tangential and normal velocities)."""
    p = np.array(bridge.mode("air").functions.params)
    x = np.concatenate([q, v]).astype(float)
    engaged = np.array([[0.0, c, float(STICK), 0.0]])
    v_plus, vt, vn = np.empty(len(q)), np.empty(1), np.empty(1)
    ok = frictional_impact(x, p, engaged, np.zeros(1), v_plus, vt, vn)
    return ok, engaged[0, 2], v_plus, vt[0], vn[0]


@pytest.mark.parametrize("ratio", [1.05, 0.95])
def test_a_block_thrown_up_a_slope_stops_and_sticks_only_when_tan_theta_is_below_mu(ratio):
    """Slipping uphill at 2 m/s it decelerates at g (sin + mu cos) and stops at the closed-form
    time and distance; there it sticks if tan(theta) <= mu, else slides back down."""
    theta, v0 = 0.3, 2.0
    mu = ratio * math.tan(theta)
    bridge = block(theta, mu)
    x0 = [0.0, 0.0, -v0, 0.0]
    ex = simulate(bridge.system("foot<", x0), x0, "foot<", 1.0, 1e-3, 1e-4)
    assert ex.status == "finished" and len(ex.transitions) == 1
    stop = ex.transitions[0]
    decel = G * (math.sin(theta) + mu * math.cos(theta))
    assert stop.time == pytest.approx(v0 / decel, abs=2e-4)  # located within the strip (eps / a)
    assert stop.state_before[0] == pytest.approx(-(v0**2) / (2 * decel), abs=1e-9)
    if ratio > 1:
        assert (stop.name, ex.final_mode) == ("stick_foot", "foot")
        np.testing.assert_allclose(ex.final_state, [stop.state_before[0], 0, 0, 0], atol=1e-12)
        ft, fn = bridge.constraint_forces("foot", ex.final_state)["foot"]
        assert ft / fn == pytest.approx(-math.tan(theta), rel=1e-12)  # friction holds it up the slope
    else:
        assert (stop.name, ex.final_mode) == ("stick_foot@foot>", "foot>")
        t = ex.t_end - stop.exit_time
        assert ex.final_state[2] == pytest.approx(G * (math.sin(theta) - mu * math.cos(theta)) * t, rel=1e-6)


def test_a_block_sliding_down_a_slope_comes_to_rest_after_the_closed_form_distance():
    theta, v0 = 0.2, 1.5
    for mu in (0.4, 0.8):
        bridge = block(theta, mu)
        x0 = [0.0, 0.0, v0, 0.0]
        ex = simulate(bridge.system("foot>", x0), x0, "foot>", 3.0, 1e-3, 1e-4)
        decel = G * (mu * math.cos(theta) - math.sin(theta))
        assert [tr.name for tr in ex.transitions] == ["stick_foot"] and ex.final_mode == "foot"
        assert ex.final_state[0] == pytest.approx(v0**2 / (2 * decel), abs=1e-9)
        # the energy lost is the friction's work mu m g cos(theta) d
        e0, e1 = ex.segments[0], ex.segments[-1]
        lost = bridge.energy("foot>", e0.x[0]) - bridge.energy("foot", e1.x[-1])
        assert lost == pytest.approx(mu * 2.0 * G * math.cos(theta) * ex.final_state[0], rel=1e-9)


def test_a_block_on_flat_ground_slips_when_a_growing_push_reaches_mu_m_g():
    mu, m, rate = 0.6, 2.0, 4.0  # push u = rate * t (N)
    bridge = block(0.0, mu, m, actuated=("x",))
    x0 = [0.0, 0.0, 0.0, 0.0]
    system = bridge.system("foot", x0)
    ex = simulate(system, x0, "foot", 5.0, 1e-3, 1e-3, control=lambda t, x: [rate * t])
    assert ex.transitions[0].name == "slip_foot>"
    assert ex.transitions[0].time == pytest.approx(mu * m * G / rate, abs=1e-9)
    # then it slides with m a = rate t - mu m g
    t = ex.t_end
    t_star = mu * m * G / rate
    assert ex.final_state[2] == pytest.approx((rate * (t**2 - t_star**2) / 2 - mu * m * G * (t - t_star)) / m, rel=1e-6)


def rod_slip_angle(mu: float, theta0: float) -> tuple[float, float]:
    """(first angle where a uniform rod pivoting on its foot from rest at theta0 needs |F| = mu N,
    the sign of F there) (m = 1, L = 1): theta_dd = 3 g sin / (2 L), theta_d^2 = 3 g (cos
    theta0 - cos) / L; from upright F / N = 3 sin (3 cos - 2) / (3 cos - 1)^2."""

    def forces(th: float) -> tuple[float, float]:
        w2 = 3 * G * (math.cos(theta0) - math.cos(th))
        acc = 1.5 * G * math.sin(th)
        xdd = 0.5 * (acc * math.cos(th) - w2 * math.sin(th))
        zdd = -0.5 * (acc * math.sin(th) + w2 * math.cos(th))
        return xdd, G + zdd

    def excess(th: float) -> float:
        f, n = forces(th)
        return abs(f) - mu * n

    grid = np.linspace(theta0 + 1e-6, 1.2, 2000)
    i = next(k for k, th in enumerate(grid) if excess(th) > 0)
    angle = brentq(excess, grid[i - 1], grid[i], xtol=1e-14)
    return angle, math.copysign(1.0, forces(angle)[0])


@pytest.mark.parametrize("mu", [0.3, 0.5])
def test_a_falling_rod_slips_where_its_friction_ratio_reaches_mu(mu):
    """Pivoting on its foot, the rod slips at the closed-form angle: backwards (the friction
    pushing it forwards) for mu = 0.3 early in the fall; for mu = 0.5, above the ratio's
    maximum (0.37), only late, forwards, as the normal force vanishes."""
    theta0 = 0.05
    bridge = rod(mu)
    x0 = [0.5 * math.sin(theta0), 0.5 * math.cos(theta0), theta0, 0.0, 0.0, 0.0]
    ex = simulate(bridge.system("foot", x0), x0, "foot", 1.5, 5e-4, 1e-4)
    first = ex.transitions[0]
    angle, friction_sign = rod_slip_angle(mu, theta0)
    assert first.name == ("slip_foot<" if friction_sign > 0 else "slip_foot>")
    assert (friction_sign > 0) == (mu < 0.37)
    assert first.state_before[2] == pytest.approx(angle, abs=2e-5)
    forces = bridge.constraint_forces("foot", first.state_before)
    assert abs(forces["foot"][0]) == pytest.approx(mu * forces["foot"][1], abs=1e-3)  # within eps (N)


def test_a_sticking_impact_inside_the_cone_is_pinocchios_impulse_dynamics():
    """Plastic: Pinocchio's impulse dynamics on both rows. With restitution c Pinocchio would
    reverse the tangential velocity too; the law keeps it at 0 (no tangential restitution), the
    KKT system with w = (0, -c v_n) written out here."""
    bridge = rod(mu=2.0)
    q, v = np.array([0.1, 0.4, 0.3]), np.array([0.2, -1.5, 0.4])
    pm, pd = bridge.model, bridge.data
    J = pin.computeFrameJacobian(pm, pd, q, pm.getFrameId("foot"), LWA)[[0, 2]]
    ok, status, v_plus, _, _ = foot_impact(bridge, q, v)
    assert ok and status == STICK
    np.testing.assert_allclose(v_plus, pin.impulseDynamics(pm, pd, q, v, J, 0.0, 0.0), atol=1e-12)
    c = 0.5
    ok, status, v_plus, _, _ = foot_impact(bridge, q, v, c)
    Minv = np.linalg.inv(pin.crba(pm, pd, q))
    impulse = np.linalg.solve(J @ Minv @ J.T, np.array([0.0, -c * (J[1] @ v)]) - J @ v)
    assert status == STICK and abs(impulse[0]) < 2.0 * impulse[1]
    np.testing.assert_allclose(v_plus, v + Minv @ J.T @ impulse, atol=1e-12)


def rod_sliding_impact(mu, c, q, v, length=1.0, m=1.0):
    """Newton's laws for a rod's end striking the floor and sliding: impulse (sigma mu P, P) at
    the end r from the centre, m dv = impulse, I dw = (r x impulse)_y, normal velocity -c v_n."""
    inertia = m * length**2 / 12
    th = q[2]
    r = np.array([-0.5 * length * math.sin(th), -0.5 * length * math.cos(th)])  # end - centre (x, z)

    def end_velocity(vc, w):  # point velocity of a body rotating by w about +y: w x r = (w r_z, -w r_x)
        return vc + w * np.array([r[1], -r[0]])

    vt, vn = end_velocity(v[:2], v[2])
    sigma = -math.copysign(1.0, vt)
    d = np.array([sigma * mu, 1.0])
    # per unit P: dv = d / m, dw = (r_z d_x - r_x d_z) / I (torque about +y of a force at r)
    dvc, dw = d / m, (r[1] * d[0] - r[0] * d[1]) / inertia
    unit = end_velocity(dvc, dw) - end_velocity(np.zeros(2), 0.0)
    P = (-c * vn - vn) / unit[1]
    return np.concatenate([v[:2] + P * dvc, [v[2] + P * dw]])


def test_a_sliding_impact_is_newtons_laws_with_the_friction_impulse_on_the_cone():
    mu = 0.2
    bridge = rod(mu)
    q, v = np.array([0.0, 0.5, 0.4]), np.array([2.5, -1.0, 0.0])  # striking while moving fast along the floor
    Jn = pin.computeFrameJacobian(bridge.model, bridge.data, q, bridge.model.getFrameId("foot"), LWA)[2]
    for c in (0.0, 0.3):
        ok, status, v_plus, vt, vn = foot_impact(bridge, q, v, c)
        assert ok and status == SLIDE
        np.testing.assert_allclose(v_plus, rod_sliding_impact(mu, c, q, v), atol=1e-12)
        assert vn == pytest.approx(-c * (Jn @ v), abs=1e-12) and vt > 0  # still sliding forwards


def test_impacts_with_friction_never_add_kinetic_energy():
    rng = np.random.default_rng(7)
    for _ in range(300):
        mu, c = rng.uniform(0, 1.5), rng.uniform(0, 1)
        bridge = rod(mu, restitution=c)
        q = np.array([0.0, 0.5, rng.uniform(-1.4, 1.4)])
        v = rng.normal(size=3)
        Jn = pin.computeFrameJacobian(bridge.model, bridge.data, q, bridge.model.getFrameId("foot"), LWA)[2]
        if Jn @ v >= 0:
            v = -v
        M = pin.crba(bridge.model, bridge.data, q)
        ok, _, v_plus, _, vn = foot_impact(bridge, q, v, c)
        assert ok and v_plus @ M @ v_plus <= v @ M @ v * (1 + 1e-12)
        assert vn >= -1e-12  # the end does not go on into the floor


def test_a_rod_dropped_on_a_rough_floor_lands_and_tips_over_with_its_energy_never_rising():
    bridge = rod(0.6)
    x0 = [0.0, 1.0, 0.4, 1.0, 0.0, -1.0]
    system = bridge.system("air", x0)
    ex = simulate(system, x0, "air", 1.5, 1e-3, 1e-4)
    assert ex.status == "finished" and ex.transitions[0].name.startswith("touchdown_foot")
    energies = [system.energy(s.mode, x) for s in ex.segments for x in s.x]
    assert max(np.diff(energies)) < 1e-6  # rk4 error only: flights and slips conserve or dissipate


def test_friction_declarations_are_checked():
    model = pin.Model()
    body = planar_floating_base(model)
    model.appendBodyToJoint(body, pin.Inertia(1.0, np.zeros(3), np.eye(3)), pin.SE3.Identity())
    add_point_frame(model, "p", body, (0, 0, 0))
    with pytest.raises(ModelError, match=r"friction -0\.1 is .*|friction must be >= 0"):
        ContactBridge(model, [PointContact("p", "p", friction=-0.1)])
    with pytest.raises(ModelError, match="needs tangential=True"):
        ContactBridge(model, [PointContact("p", "p", friction=0.5, tangential=False)])
    with pytest.raises(ModelError, match="may not contain '<' or '>'"):
        ContactBridge(model, [PointContact("p>", "p", friction=0.5)])


def test_a_slip_without_consistent_forces_is_stopped_by_a_tangential_impulse():
    """Painleve: a rod (inertia m a^2 / 3 about its centre, a = L / 2) slipping on its end
    towards -x while leaning towards +x by theta has the Delassus diagonal
    (1 + 3 sin^2 theta - 3 mu sin theta cos theta) / m, negative for mu = 2 at theta = 0.8:
    the slipping mode has no contact forces (its field and forces are nan: past the model's
    range), and a slip onset into it is resolved by sticking the end with a tangential impulse,
    which adds no energy."""
    mu, theta = 2.0, 0.8
    diagonal = 1 + 3 * math.sin(theta) ** 2 - 3 * mu * math.sin(theta) * math.cos(theta)  # m = 1 kg
    assert diagonal < 0
    bridge = rod(mu)
    x = np.array([0.5 * math.sin(theta), 0.5 * math.cos(theta), theta, -0.1, 0.0, 0.0])  # the end slides at -0.1 m/s
    assert np.all(np.isnan(bridge.constraint_forces("foot<", x)["foot"]))
    assert np.all(np.isnan(bridge.field("foot<")(0.0, x, None)[3:]))
    bridge.reset_counters()
    status, image = np.empty(1), np.empty(6)
    p = np.array(bridge.mode("foot").functions.params)
    assert mode_change(x, np.zeros(0), p, 0, -1.0, False, status, image)
    assert status[0] == S_ACTIVE and bridge.counters()["painleve_sticks"] == 1
    q, v = image[:3], image[3:]
    J = pin.computeFrameJacobian(bridge.model, bridge.data, q, bridge.model.getFrameId("foot"), LWA)
    np.testing.assert_allclose(J[[0, 2]] @ v, 0.0, atol=1e-12)  # the end stopped
    M = pin.crba(bridge.model, bridge.data, q)
    assert v @ M @ v <= x[3:] @ M @ x[3:]


def test_an_impact_at_a_state_far_outside_any_motion_has_no_outcome():
    """An adaptive step too long for a stiff controller evaluates the guards, and with them the
    impact law, at stage states with speeds above 1e150 (the quadruped's first DOP853 trial at
    h = 0.02 s): there its kinetic energy overflows. The law has no outcome (the guards are
    nan: past the model's range, where the integrator shortens the step); a state of ordinary
    size keeps its result."""
    bridge = rod(mu=0.5)
    q = np.array([0.1, 0.4, 0.3])
    assert not foot_impact(bridge, q, np.array([0.2, -1e200, 0.4]))[0]
    ok, _, v_plus, _, _ = foot_impact(bridge, q, np.array([0.2, -1.5, 0.4]))
    assert ok and np.all(np.isfinite(v_plus))


#: No friction cones: the plain least-norm solution.
NO_CONES = np.empty((0, 3))


# -- rows that depend on one another beside a sliding row --------------------------------------------
def _delassus(J, W, M):
    """A = J M^-1 W^T and M^-1 W^T for constraint rows J, force rows W and inertia M."""
    MWt = np.linalg.solve(M, W.T)
    return J @ MWt, MWt


def test_two_stuck_corners_beside_a_sliding_row_take_the_least_norm_share_and_a_unique_motion():
    # A body's two stuck corners at one height have the same tangential row (four rows on three
    # dofs of the body), and a third contact slides (its force row W = N + s mu T differs from its
    # constraint row). A is singular through the stuck rows alone: the motion is unique, and the
    # forces are the least-norm ones, the corners sharing their tangential force equally.
    rng = np.random.default_rng(7)
    n = 4
    B = rng.normal(size=(n, n))
    M = B @ B.T + n * np.eye(n)
    t, n0, n2, n_tip, t_tip = (rng.normal(size=n) for _ in range(5))
    J = np.array([t, n0, t, n2, n_tip])
    W = J.copy()
    W[4] = n_tip + 0.3 * t_tip
    A, MWt = _delassus(J, W, M)
    b = J @ rng.normal(size=n)  # the rows' right side from a motion: in A's range
    y = b.copy()
    assert solve_rows(A, y, 5, False, MWt, NO_CONES)
    assert np.allclose(A @ y, b, atol=1e-12)
    assert y[0] == pytest.approx(y[2], abs=1e-12)
    assert np.allclose(y, np.linalg.pinv(A) @ b, atol=1e-10)
    # the same motion as the regular system without the second corner's tangential row
    keep = [0, 1, 3, 4]
    reduced = np.linalg.solve(A[np.ix_(keep, keep)], b[keep])
    assert np.allclose(MWt @ y, MWt[:, keep] @ reduced, atol=1e-12)


def test_a_sliding_row_whose_forces_are_not_unique_in_their_motion_is_refused():
    # Two independent rows, one sliding, with the friction coefficient at which A turns singular:
    # the null vector of A moves the body (M^-1 W^T has full rank), so the motion is not unique,
    # Painleve's case; and a lone sliding row with a zero diagonal.
    rng = np.random.default_rng(3)
    n = 3
    M = np.diag([2.0, 1.0, 0.5])
    N0, N1, T1 = (rng.normal(size=n) for _ in range(3))
    J = np.array([N0, N1])

    def det(mu):
        return np.linalg.det(_delassus(J, np.array([N0, N1 + mu * T1]), M)[0])

    mu = -det(0.0) / (det(1.0) - det(0.0))  # det is linear in mu: one column holds it
    A, MWt = _delassus(J, np.array([N0, N1 + mu * T1]), M)
    assert abs(np.linalg.det(A)) < 1e-12 * np.abs(A).max() ** 2
    y = J @ rng.normal(size=n)
    assert not solve_rows(A, y, 2, False, MWt, NO_CONES)
    assert not solve_rows(np.zeros((1, 1)), np.array([0.0]), 1, False, np.ones((n, 1)), NO_CONES)


def test_two_stuck_corners_share_their_friction_by_their_capacities():
    # A brick (x, z, pitch; 4 kg, 0.1 kg m^2) on two stuck corners at (-0.3, -0.1) and
    # (0.3, -0.1) from its centre, pushed along x by 14 N: the normal forces are determined, the
    # tangential ones only in their sum. Each corner takes the share mu_i n_i / sum(mu n) of it
    # (the least-norm share, 7 N each, would put the corner of mu = 0.1 outside its cone).
    m, inertia = 4.0, 0.1
    Minv = np.diag([1 / m, 1 / m, 1 / inertia])
    J = np.array([[1.0, 0.0, -0.1], [0.0, 1.0, 0.3], [1.0, 0.0, -0.1], [0.0, 1.0, -0.3]])  # t_a, n_a, t_b, n_b
    applied = np.array([-14.0, -m * 9.81, 0.0])
    b = -J @ Minv @ applied  # the rows' accelerations held at 0: J Minv (applied + J^T y) = 0
    A = J @ Minv @ J.T
    mu = (0.1, 1.0)
    y = b.copy()
    assert solve_rows(A, y, 4, True, Minv @ J.T, np.array([[0, 1, mu[0]], [2, 3, mu[1]]]))
    assert np.allclose(A @ y, b, atol=1e-12)
    capacity = mu[0] * y[1] + mu[1] * y[3]
    assert y[0] + y[2] == pytest.approx(14.0, abs=1e-12)
    assert y[0] == pytest.approx(14.0 * mu[0] * y[1] / capacity, abs=1e-12)
    assert y[0] / (mu[0] * y[1]) == pytest.approx(y[2] / (mu[1] * y[3]), abs=1e-12)  # the same share of each cone
    least = b.copy()
    assert solve_rows(A, least, 4, True, Minv @ J.T, NO_CONES) and least[0] == pytest.approx(7.0, abs=1e-12)
