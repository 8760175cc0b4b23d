"""Simultaneous impacts resolved under one impact law (robots/bridge/joint.py, impacts.py), on the rod dropped
on its two ends: it bounces flat, loses the closed-form energy, and its outcome is continuous in
the initial tilt; the law against Pinocchio's impulse dynamics; complementarity and energy."""

import numpy as np
import pinocchio as pin
import pytest
from legsim.robots import rod
from legsim.robots.bridge import impacts

from legsim import simulate

C, G = 0.5, 9.81


def drop(theta0: float, t_final: float = 1.2, eps: float = 1e-3):
    model = rod.make({"restitution": C})
    x0 = np.array([0.0, 1.0, theta0, 0.0, 0.0, 0.0])
    return model, simulate(model.system, x0, "air", t_final, 1e-3, eps, "rk4")


def params(bridge):
    """A mode's parameter array of the bridge (every mode holds the contacts' records)."""
    return np.array(bridge.mode(bridge.mode_name(())).functions.params)


def newton_impact(bridge, rows, q, v):
    """(v+, each contact's normal impulse) of the Newton impact of rows ((name, restitution))."""
    names = [c.name for c in bridge.contacts]
    contacts = np.array([names.index(name) for name, _ in rows], dtype=np.int64)
    coeff = np.array([c for _, c in rows])
    v_plus, normal = np.empty(len(v)), np.empty(len(rows))
    impacts.newton_impact(np.concatenate([q, v]), params(bridge), contacts, coeff, len(rows), v_plus, normal)
    return v_plus, dict(zip([name for name, _ in rows], normal, strict=True))


def joint_impact(bridge, strikers, q, v, restitution):
    """(v+, the strikers that take part) of their joint impact, no contact held."""
    names = [c.name for c in bridge.contacts]
    index = np.array([names.index(name) for name in strikers], dtype=np.int64)
    coeff = np.array([restitution[name] for name in strikers])
    v_plus, taking = np.empty(len(v)), np.zeros(len(strikers))
    x = np.concatenate([q, v])
    impacts.joint_impact(x, params(bridge), np.zeros(0, dtype=np.int64), 0, index, len(strikers), coeff, v_plus, taking)
    return v_plus, [name for name, k in zip(strikers, taking, strict=True) if k == 1.0]


def kinetic(bridge, x):
    q, v = x[:3], x[3:6]
    return 0.5 * float(v @ pin.crba(bridge.model, bridge.data, q) @ v)


def test_a_flat_rod_bounces_flat_and_loses_the_closed_form_energy():
    model, ex = drop(0.0)
    joints = [tr for tr in ex.transitions if tr.name == "joint_a+b"]
    assert ex.status == "finished" and len(joints) == len(ex.transitions) >= 3
    bridge = model.info["bridge"]
    for tr in joints:
        v = tr.state_before[4]
        # both ends strike together: the centre's vertical speed reverses by c, no spin starts
        assert tr.state_after[4] == pytest.approx(-C * v, rel=1e-12)
        assert abs(tr.state_after[5]) < 1e-12
        lost = kinetic(bridge, tr.state_before) - kinetic(bridge, tr.state_after)
        assert lost == pytest.approx(0.5 * (1 - C * C) * v * v, rel=1e-12)  # m = 1 kg
    assert np.max(np.abs(np.concatenate([s.x[:, 2] for s in ex.segments]))) < 1e-12


def test_the_outcome_is_continuous_in_the_initial_tilt_inside_the_landing_window():
    _, flat = drop(0.0)
    gaps = []
    for theta0 in (1e-9, -1e-9, 1e-7, -1e-7):
        _, tilted = drop(theta0)
        assert [tr.name for tr in tilted.transitions] == [tr.name for tr in flat.transitions]
        gaps.append(np.max(np.abs(tilted.final_state - flat.final_state)) / abs(theta0))
    # the tilt moves the outcome in proportion to it: no jump at theta0 = 0
    assert max(gaps) < 10.0


def test_the_joint_law_is_pinocchios_impulse_dynamics_for_one_restitution():
    bridge = rod.make_bridge({"mass": 1.3, "length": 0.8, "restitution": C, "g": G})
    q = np.array([0.2, 0.0, 0.0])
    v = np.array([0.4, -2.0, 0.7])
    v_plus, normal = newton_impact(bridge, [("a", C), ("b", C)], q, v)
    J = np.vstack(
        [
            pin.computeFrameJacobian(
                bridge.model, bridge.data, q, bridge.model.getFrameId(f), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
            )[2]
            for f in ("end_a", "end_b")
        ]
    )
    expected = pin.impulseDynamics(bridge.model, bridge.data, q, v, J, C, 0.0)
    np.testing.assert_allclose(v_plus, expected, rtol=0, atol=1e-12)
    assert normal["a"] > 0 and normal["b"] > 0


def two_points_on_one_side(c: float):
    """A body with two contacts on the same side of its centre (x = 0.5 and 0.3 m): an impulse at
    the outer one lifts the inner one, so a joint law on both can need to pull on it."""
    from legsim.robots.bridge import ContactBridge, PointContact, add_point_frame, planar_floating_base

    model = pin.Model()
    body = planar_floating_base(model)
    model.appendBodyToJoint(body, pin.Inertia(1.0, np.zeros(3), np.diag([0.1] * 3)), pin.SE3.Identity())
    add_point_frame(model, "pa", body, (0.5, 0.0, 0.0))
    add_point_frame(model, "pb", body, (0.3, 0.0, 0.0))
    return ContactBridge(
        model,
        [
            PointContact("a", "pa", restitution=c, tangential=False),
            PointContact("b", "pb", restitution=c, tangential=False),
        ],
    )


def test_an_adhesive_contact_is_dropped_and_the_impact_solved_again():
    bridge = two_points_on_one_side(0.9)
    q, v = np.zeros(3), np.array([0.0, 0.0284, 0.5467])  # both ends approaching (-0.245, -0.136 m/s)
    normal_rows = {
        n: pin.computeFrameJacobian(
            bridge.model, bridge.data, q, bridge.model.getFrameId(f"p{n}"), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        )[2]
        for n in "ab"
    }
    assert normal_rows["a"] @ v < 0 and normal_rows["b"] @ v < 0
    _, both = newton_impact(bridge, [("a", 0.9), ("b", 0.9)], q, v)
    assert both["b"] < 0  # one law on both would pull b onto the floor
    v_plus, taking = joint_impact(bridge, ["a", "b"], q, v, {"a": 0.9, "b": 0.9})
    assert taking == ["a"]
    assert normal_rows["a"] @ v_plus == pytest.approx(-0.9 * (normal_rows["a"] @ v), rel=1e-12)
    assert normal_rows["b"] @ v_plus >= 0.0  # b leaves the floor by itself


def test_a_contact_the_impact_drives_into_the_floor_joins_it():
    # Only end a approaches; the impulse it takes spins the rod and drives end b down: b joins
    # the impact plastically (no penetration), and both impulses push.
    bridge = rod.make_bridge({"mass": 1.0, "length": 1.0, "restitution": C, "g": G})
    q, v = np.zeros(3), np.array([0.0, -1.0, 3.0])  # end a at -2.5 m/s, end b rising at +0.5 m/s
    v_plus, taking = joint_impact(bridge, ["a", "b"], q, v, {"a": C, "b": C})
    assert taking == ["a", "b"]
    end_b = v_plus[1] + 0.5 * v_plus[2]
    assert abs(end_b) < 1e-12 and v_plus[1] - 0.5 * v_plus[2] == pytest.approx(C * 2.5, rel=1e-12)


def test_different_restitutions_never_add_kinetic_energy():
    bridge = rod.make_bridge({"mass": 1.0, "length": 1.0, "restitution": C, "g": G})
    rng = np.random.default_rng(7)
    M = pin.crba(bridge.model, bridge.data, np.zeros(3))
    for _ in range(200):
        v = rng.normal(size=3)
        c_a, c_b = rng.uniform(0.0, 1.0, size=2)
        v_plus, _ = joint_impact(bridge, ["a", "b"], np.zeros(3), v, {"a": c_a, "b": c_b})
        assert v_plus @ M @ v_plus <= v @ M @ v * (1 + 1e-12) + 1e-15


def test_the_rod_comes_to_rest_by_its_joint_continuation_without_an_accumulation_warning():
    """Dropped flat past its Zeno time (1.3546 s for c = 0.5 from 1 m: sqrt(2/g) (1 + 2c/(1 - c))),
    the rod's joint bounces accumulate and the joint's continuation (``rest_a+b``, both ends
    plastic) takes it into the mode with both ends down: a resolved accumulation, of which the
    run does not warn. Without the continuation the same run warns, naming the remedy."""
    model = rod.make({"restitution": C})
    x0 = np.array([0.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    ex = simulate(model.system, x0, "air", 2.0, 1e-3, 1e-4, "rk4", landing="aim")
    zeno = np.sqrt(2.0 / G) * (1.0 + 2.0 * C / (1.0 - C))
    assert ex.status == "finished" and ex.transitions[-1].name == "rest_a+b" and ex.segments[-1].mode == "a+b"
    assert abs(ex.transitions[-1].time - zeno) < 5e-3  # the continuation comes within a few windows of it
    assert [w.kind for w in ex.warnings] == []
    plain = simulate(model.system, x0, "air", 1.5, 1e-3, 1e-4, "rk4", landing="aim", continuation=False)
    accumulations = [w for w in plain.warnings if w.kind == "accumulation"]
    assert len(accumulations) == 1 and "run with continuation" in accumulations[0].message
