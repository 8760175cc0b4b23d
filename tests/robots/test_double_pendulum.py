"""Double pendulum with a mechanical stop (paper 003 Section V): Pinocchio's dynamics against the
textbook closed form, the impact law eq. (30), the stop force eq. (31), the plastic and Zeno runs
(the paper's relaxed execution, and by default resting where the impacts accumulate)."""

import itertools
import math

import numpy as np
import pinocchio as pin
import pytest
from legsim.robots import double_pendulum as dp

from legsim import simulate
from legsim.errors import SceneError
from legsim.graph import reachable_modes

# Deliberately not the defaults, so a parameter that is not wired through would show.
P = dict(m1=1.3, m2=0.7, L1=0.9, L2=1.2, g=9.81)
DEFAULTS = dict(m1=1.0, m2=1.0, L1=1.0, L2=1.0, g=9.81)


def mass_matrix(q, m1, m2, L1, L2, g):
    """Textbook mass matrix of the double pendulum with point masses at the link ends
    (theta1 from the downward vertical, theta2 relative to link 1)."""
    c2 = math.cos(q[1])
    m11 = (m1 + m2) * L1**2 + m2 * L2**2 + 2 * m2 * L1 * L2 * c2
    m12 = m2 * L2**2 + m2 * L1 * L2 * c2
    return np.array([[m11, m12], [m12, m2 * L2**2]])


def coriolis(q, qd, m1, m2, L1, L2, g):
    """C(q, qd) qd."""
    s2 = math.sin(q[1])
    return np.array([-m2 * L1 * L2 * s2 * (2 * qd[0] * qd[1] + qd[1] ** 2), m2 * L1 * L2 * s2 * qd[0] ** 2])


def gravity(q, m1, m2, L1, L2, g):
    """dV/dq with V = -(m1 + m2) g L1 cos(theta1) - m2 g L2 cos(theta1 + theta2)."""
    s1, s12 = math.sin(q[0]), math.sin(q[0] + q[1])
    return np.array([(m1 + m2) * g * L1 * s1 + m2 * g * L2 * s12, m2 * g * L2 * s12])


def energy(x, p=P):
    q, qd = x[:2], x[2:]
    m1, m2, L1, L2, g = p["m1"], p["m2"], p["L1"], p["L2"], p["g"]
    V = -(m1 + m2) * g * L1 * math.cos(q[0]) - m2 * g * L2 * math.cos(q[0] + q[1])
    return 0.5 * qd @ mass_matrix(q, **p) @ qd + V


def eq30(x, c, p=P):
    """Paper 003 eq. (30) with the closed-form M^-1."""
    Minv = np.linalg.inv(mass_matrix(x[:2], **p))
    return np.array([x[0], x[1], x[2] - (1 + c) * x[3] * Minv[0, 1] / Minv[1, 1], -c * x[3]])


def eq31(x, p=P):
    """Paper 003 eq. (31) as printed."""
    q, qd = x[:2], x[2:]
    Minv = np.linalg.inv(mass_matrix(q, **p))
    return -Minv[1] @ (coriolis(q, qd, **p) + gravity(q, **p)) / Minv[1, 1]


def random_states(n, seed=0, at_stop=False):
    rng = np.random.default_rng(seed)
    xs = np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-2, 2, n), rng.normal(0, 2, n), rng.normal(0, 2, n)])
    if at_stop:
        xs[:, 1] = 0.0
    return xs


def test_pinocchio_mass_matrix_bias_and_gravity_equal_the_closed_form():
    model = dp.pinocchio_model(**P)
    data = model.createData()
    for x in random_states(20):
        q, qd = x[:2], x[2:]
        np.testing.assert_allclose(pin.crba(model, data, q), mass_matrix(q, **P), rtol=0, atol=1e-12)
        G = pin.computeGeneralizedGravity(model, data, q)
        np.testing.assert_allclose(G, gravity(q, **P), rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            pin.nonLinearEffects(model, data, q, qd) - G, coriolis(q, qd, **P), rtol=0, atol=1e-12
        )


def test_unconstrained_field_energy_and_geometry_equal_the_closed_form():
    model = dp.make(P, {"stop": False})
    bridge = model.info["bridge"]
    f = model.system.mode("unconstrained").field
    for x in random_states(20, seed=1):
        q, qd = x[:2], x[2:]
        qdd = np.linalg.solve(mass_matrix(q, **P), -(coriolis(q, qd, **P) + gravity(q, **P)))
        np.testing.assert_allclose(f(0.0, x, None), np.concatenate([qd, qdd]), rtol=0, atol=1e-11)
        assert model.system.energy("unconstrained", x) == pytest.approx(energy(x), abs=1e-12)
        tip = model.geometry("unconstrained", x)["link2"][1]
        expected = [
            P["L1"] * math.sin(q[0]) + P["L2"] * math.sin(q[0] + q[1]),
            -P["L1"] * math.cos(q[0]) - P["L2"] * math.cos(q[0] + q[1]),
        ]
        np.testing.assert_allclose(tip, expected, atol=1e-12)
    assert bridge.counters()["kkt"] == 0


@pytest.mark.parametrize("c", [0.0, 0.3, 0.5, 1.0])
def test_impact_reset_is_paper_003_eq_30(c):
    model = dp.make(P, {"stop": {"restitution": c}})
    resets = [tr.reset for tr in model.system.outgoing("unconstrained")]
    assert len(resets) == (2 if c == 0 else 1)  # c = 0: sticking and separating impacts share eq. (30)
    for x in random_states(10, seed=2, at_stop=True):
        x[3] = -abs(x[3])  # approaching the stop
        for reset in resets:
            np.testing.assert_allclose(reset(x), eq30(x, c), rtol=0, atol=1e-12)
        if c == 1.0:  # an elastic impact keeps the kinetic energy
            assert energy(resets[0](x)) == pytest.approx(energy(x), rel=1e-12)


def test_constraint_force_is_paper_003_eq_31():
    model = dp.make(P, {"stop": {"restitution": 0.0}})
    bridge = model.info["bridge"]
    f = model.system.mode("constrained").field
    for x in random_states(20, seed=3, at_stop=True):
        lam = bridge.constraint_forces("constrained", x)["stop"]
        # Eq. (31) as printed is the free acceleration of theta2 times 1/(M^-1)_22, > 0 when link 2
        # would leave the stop; the bridge reports the force the stop exerts (> 0 while it holds
        # link 2 in theta2 >= 0), the same magnitude with the opposite sign. Both vanish together.
        assert lam.shape == (1,)
        assert lam[0] == pytest.approx(-eq31(x), abs=1e-11)
        # and the constrained field keeps theta2 still: M qdd + b = J^T lambda, qdd2 = 0
        qdd = f(0.0, x, None)[2:]
        assert abs(qdd[1]) < 1e-12
        rhs = -(coriolis(x[:2], x[2:], **P) + gravity(x[:2], **P)) + np.array([0.0, lam[0]])
        np.testing.assert_allclose(mass_matrix(x[:2], **P) @ qdd, rhs, atol=1e-11)


def test_constraint_force_agrees_with_pinocchio_forward_dynamics():
    model = dp.make(P, {"stop": {"restitution": 0.0}})
    bridge = model.info["bridge"]
    pm, pd = bridge.model, bridge.model.createData()
    J = np.array([[0.0, 1.0]])
    for x in random_states(5, seed=4, at_stop=True):
        a = pin.forwardDynamics(pm, pd, x[:2], x[2:], np.zeros(2), J, np.zeros(1))
        np.testing.assert_allclose(model.system.mode("constrained").field(0.0, x, None)[2:], a, atol=1e-12)
        assert bridge.constraint_forces("constrained", x)["stop"][0] == pytest.approx(pd.lambda_c[0], abs=1e-12)


@pytest.mark.parametrize("method,h,eps", [("rk4", 1e-3, 1e-3), ("euler", 1e-3, 0.2)])
def test_plastic_stop_enters_constrained_mode_and_leaves_where_eq_31_changes_sign(method, h, eps):
    model = dp.make(effects={"stop": {"restitution": 0.0}})
    x0 = [model.initial_state[n] for n in dp.STATE_NAMES]
    ex = simulate(model.system, x0, "unconstrained", 3.0, h, eps, method=method)
    assert ex.status == "finished"
    names = [tr.name for tr in ex.transitions]
    # The first impact finds link 2 pulling away (lambda+ < 0): it separates at once; the second sticks.
    assert names[:3] == ["graze_stop", "impact_stop", "release_stop"]
    for seg in ex.segments:
        if seg.mode != "constrained":
            continue
        assert np.abs(seg.x[:, 1]).max() < 1e-9 and np.abs(seg.x[:, 3]).max() < 1e-9
        # the stop holds while eq. (31) is negative (its force, -(31), positive) ...
        assert all(eq31(x, DEFAULTS) < 0 for x in seg.x[:-1])
    release = ex.transitions[2]
    # ... and lets go where it changes sign. With theta2 = 0 eq. (31) is proportional to
    # sin(theta1) (the Coriolis terms vanish), so the release is at theta1 = 0 exactly.
    assert abs(eq31(release.state_before, DEFAULTS)) < 1e-8
    assert abs(release.state_before[0]) < 1e-8


def test_restitution_half_is_zeno_and_the_run_carries_on_past_the_accumulation():
    # The paper's relaxed execution (continuation=False): the stop chatters in its strip.
    c, eps, t_final = 0.5, 1e-3, 3.0
    model = dp.make(effects={"stop": {"restitution": c}})
    x0 = [model.initial_state[n] for n in dp.STATE_NAMES]
    ex = simulate(model.system, x0, "unconstrained", t_final, 1e-3, eps, continuation=False)
    assert ex.status == "finished" and ex.t_end == t_final
    trs = ex.transitions
    flights = np.array([trs[i + 1].time - trs[i].exit_time for i in range(len(trs) - 1)])
    # Flights between impacts shrink geometrically with ratio c: for a nearly constant relative
    # acceleration a bounce leaving at c w returns after 2 c w / a. The first ones are long enough
    # for the acceleration to vary, hence the 2% tolerance and starting at the second ratio.
    ratios = flights[2:14] / flights[1:13]
    assert np.all(np.abs(ratios - c) < 0.02), ratios
    # Accumulation: the physical time left after impact k is flights[k] * c / (1 - c); past
    # the 20th impact it is below 1e-6 s, yet the run continues to t_final ...
    t_acc = trs[20].time
    assert t_acc < 1.5 < t_final
    after = [tr for tr in trs if tr.time > t_acc]
    # ... without stalling: each later transition still spends about eps in its strip, so their
    # number stays near (t_final - t_acc) / eps rather than exploding.
    holds = np.array([tr.exit_time - tr.time for tr in after])
    assert holds.min() > 0.5 * eps
    assert len(after) < 1.1 * (t_final - t_acc) / eps
    for seg in ex.segments:  # and the link never passes the stop by more than the strip
        assert seg.x[:, 1].min() >= -eps
    # ... and the run says that past the accumulation its state is held, not moved
    (warning,) = ex.warnings
    assert warning.kind == "accumulation" and warning.details["transition"] == "bounce_stop"
    assert t_acc - 0.05 < warning.time < t_acc


def test_effects_build_only_what_is_asked():
    free = dp.make(effects={"stop": False}).system
    assert reachable_modes(free, "unconstrained") == ["unconstrained"]
    assert free.outgoing("unconstrained") == ()

    plastic = dp.make(effects={"stop": {"restitution": 0.0}}).system
    assert sorted(reachable_modes(plastic, "unconstrained")) == ["constrained", "unconstrained"]
    assert {tr.name for tr in plastic.outgoing("unconstrained")} == {"impact_stop", "graze_stop"}
    assert [tr.name for tr in plastic.outgoing("constrained")] == ["release_stop"]

    bouncy = dp.make(effects={"stop": {"restitution": 0.5}}).system
    assert reachable_modes(bouncy, "unconstrained") == ["unconstrained"]
    assert [(tr.name, tr.target) for tr in bouncy.outgoing("unconstrained")] == [("bounce_stop", "unconstrained")]


def test_damping_is_computed_only_when_asked_and_dissipates():
    x0 = np.array([math.radians(30), math.radians(25), 0.0, 0.0])
    plain = dp.make(effects={"stop": False})
    simulate(plain.system, x0, "unconstrained", 0.5, 1e-3, 1e-3)
    assert plain.counters()["damping_evals"] == 0 and plain.counters()["aba"] > 0

    b1, b2 = 0.3, 0.2
    damped = dp.make(effects={"stop": False, "damping": {"b1": b1, "b2": b2}})
    f = damped.system.mode("unconstrained").field
    for x in random_states(5, seed=5):
        q, qd = x[:2], x[2:]
        rhs = -(coriolis(q, qd, **DEFAULTS) + gravity(q, **DEFAULTS)) - np.array([b1, b2]) * qd
        np.testing.assert_allclose(f(0.0, x, None)[2:], np.linalg.solve(mass_matrix(q, **DEFAULTS), rhs), atol=1e-11)
    damped.info["bridge"].reset_counters()
    ex = simulate(damped.system, x0, "unconstrained", 2.0, 1e-3, 1e-3)
    counts = damped.counters()
    # one damping term per dynamics solve asked for (cache_hits: served by the last solve)
    assert counts["damping_evals"] == counts["aba"] + counts["cache_hits"] and counts["aba"] > 0
    # dE/dt = -b . qd^2 <= 0: the energy never rises (beyond RK4's local error)
    E = np.array([damped.system.energy("unconstrained", x) for x in ex.segments[0].x])
    assert np.all(np.diff(E) < 1e-9) and E[-1] < E[0] - 0.1


def test_by_default_the_stop_rests_in_the_constrained_mode_and_is_released_where_eq_31_changes_sign():
    # c = 0.5 with the default continuation (window h + eps): the accumulating impacts end in a
    # plastic impact into the constrained mode, the straight pendulum swings as one body, and
    # the stop lets go where eq. (31) changes sign: at theta1 = 0 for unit masses and lengths.
    h = eps = 1e-3
    window = h + eps
    model = dp.make(effects={"stop": {"restitution": 0.5}})
    x0 = [model.initial_state[n] for n in dp.STATE_NAMES]
    ex = simulate(model.system, x0, "unconstrained", 2.5, h, eps)
    names = [tr.name for tr in ex.transitions]
    assert names.count("rest_stop") == 1 and names[-2:] == ["rest_stop", "release_stop"] and ex.warnings == []
    rest, release = ex.transitions[-2], ex.transitions[-1]
    assert abs(release.state_before[0]) < 1e-8 and abs(eq31(release.state_before, DEFAULTS)) < 1e-8
    # in the constrained mode theta2 and its rate stay at the stop and eq. (31) holds the link
    for t in np.linspace(rest.exit_time, release.time, 7)[1:-1]:
        mode, x = ex.state_at(t)
        assert mode == "constrained" and abs(x[1]) < 1e-9 and abs(x[3]) < 1e-9 and eq31(x, DEFAULTS) < 0
    # the rest is a plastic impact (eq. (30) with c = 0) at the crossing that ends the first
    # flight no longer than the window, the flights before it shrinking and all longer
    np.testing.assert_allclose(rest.state_after, eq30(rest.state_before, 0.0, DEFAULTS), atol=1e-12)
    bounces = ex.transitions[:-2]
    flights = [b.time - a.exit_time for a, b in zip(bounces, [*bounces[1:], rest], strict=True)]
    assert flights[-1] <= window < min(flights[:-1]) and np.all(np.diff(flights) < 0)
    # the bounces before it are those of the plain run, and cost at most a fiftieth of its transitions
    plain = simulate(model.system, x0, "unconstrained", 2.5, h, eps, continuation=False)
    np.testing.assert_allclose(
        [tr.time for tr in bounces], [tr.time for tr in plain.transitions[: len(bounces)]], atol=1e-12
    )
    assert len(plain.transitions) >= 50 * len(names)


def test_the_bounce_names_its_rest_which_is_taken_only_where_the_stop_pushes():
    model = dp.make(effects={"stop": {"restitution": 0.5}})
    (bounce,) = model.system.outgoing("unconstrained")
    (release,) = model.system.outgoing("constrained")
    rest = bounce.continuation
    assert (bounce.name, rest.name, rest.target, release.name) == (
        "bounce_stop",
        "rest_stop",
        "constrained",
        "release_stop",
    )
    # the rest's reset is the plastic impact, eq. (30) with c = 0
    x = np.array([-0.6, -1e-6, 0.2, -0.05])
    np.testing.assert_allclose(rest.reset(x), eq30(x, 0.0, DEFAULTS), atol=1e-12)
    # The core takes it only where its image lies in the constrained mode's domain, where the
    # release guard (the stop's force) is >= 0: at theta1 = -0.6 eq. (31) pushes link 2 onto the
    # stop, at theta1 = +0.6 it would pull it off, and an accumulating impact bounces instead.
    assert eq31(rest.reset(x), DEFAULTS) < 0 and release.guard_value(rest.reset(x)) > 0
    y = np.array([0.6, -1e-6, 0.2, -0.05])
    assert eq31(rest.reset(y), DEFAULTS) > 0 and release.guard_value(rest.reset(y)) < 0
    # the `zeno` effect sets the window of the accumulation rule, which scenes pass to simulate
    windowed = dp.make(effects={"stop": {"restitution": 0.5}, "zeno": {"window": 5e-3}})
    assert windowed.info["zeno_window"] == 5e-3 and "zeno_window" not in model.info
    with pytest.raises(SceneError, match=r"effects\.zeno\.window"):
        dp.make(effects={"zeno": {"window": -1.0}})


def test_at_c_half_the_run_to_6_s_converges_as_eps_and_h_shrink_and_link_1_keeps_swinging():
    # Past each accumulation the link rests on the stop and is released where eq. (31) changes
    # sign (theta1 = 0); without continuation link 1 froze with the chattering stop. The final
    # state converges: each difference between successive levels (eps / 10, h / 2, so the
    # default window h + eps about halves) at most half the previous one.
    model = dp.make(effects={"stop": {"restitution": 0.5}})
    x0 = [model.initial_state[n] for n in dp.STATE_NAMES]
    finals = []
    for h, eps in ((1e-3, 1e-3), (5e-4, 1e-4), (2.5e-4, 1e-5), (1.25e-4, 1e-6)):
        ex = simulate(model.system, x0, "unconstrained", 6.0, h, eps)
        assert ex.status == "finished" and ex.warnings == []
        names = [tr.name for tr in ex.transitions]
        assert names.count("rest_stop") == names.count("release_stop") == 2
        releases = [tr.state_before for tr in ex.transitions if tr.name == "release_stop"]
        assert max(abs(x[0]) for x in releases) < 1e-8
        # link 1 swings through the last half second (at -1.837 rad/s at 6 s once converged)
        last = np.array(ex.sample(np.linspace(5.5, 6.0, 51)).states)
        assert np.ptp(last[:, 0]) > 0.1 and abs(ex.final_state[2]) > 1.5
        finals.append(ex.final_state)
    diffs = [float(np.max(np.abs(a - b))) for a, b in itertools.pairwise(finals)]
    assert diffs[1] <= 0.5 * diffs[0] and diffs[2] <= 0.5 * diffs[1], diffs
    assert diffs[-1] < 5e-3
    # the paper's relaxed execution holds link 1 in the chattering stop's strip from 1.42 s on,
    # its velocity frozen with it
    plain = simulate(model.system, x0, "unconstrained", 6.0, 1e-3, 1e-3, continuation=False)
    held = np.array(plain.sample(np.linspace(5.5, 6.0, 51)).states)
    assert np.ptp(held[:, 0]) == 0.0 and plain.final_state[2] == held[0, 2]


def test_scene_refuses_an_initial_state_past_the_stop_by_more_than_eps():
    # The guard max(theta2 - pos, theta2d) counts theta2 = -1 at rest as inside the free mode, so
    # the run "finished" 1 rad past the stop; the bridge's initial check must name it.
    from legsim.scene import load_scene

    with pytest.raises(SceneError) as err:
        load_scene("double_pendulum_plastic", overrides=["initial.state.theta2=-1"])
    msg = str(err.value)
    assert "theta2 = -1" in msg and "stop 'stop'" in msg and "by 1 rad >" in msg and "'unconstrained'" in msg
    eps = load_scene("double_pendulum_plastic").integrator["eps"]
    # Within the strip (depth < eps) is a legitimate start: the run enters the strip at once.
    scene = load_scene("double_pendulum_plastic", overrides=[f"initial.state.theta2={-0.5 * eps!r}"])
    assert scene.initial_state[1] == pytest.approx(-0.5 * eps)
    check = scene.model.info["initial_check"]
    # In the constrained mode the stop is active: no depth is measured against it.
    assert check("constrained", np.array([0.5, -1.0, 0.0, 0.0]), eps) is None
    assert check("unconstrained", np.array([0.5, -2.0 * eps, 0.0, 0.0]), eps) is not None


# -- the controller effect: PD on the shoulder --------------------------------------------------
def pd_torque(x, kp, kd, target):
    """u = kp (target - theta1) - kd theta1d (N m), computed here from its definition."""
    return kp * (target - x[0]) - kd * x[2]


def test_controller_effect_actuates_the_shoulder_only_when_asked():
    # Off (the default): no control, no actuated joint, no input, no actuation term.
    plain = dp.make(effects={"stop": {"restitution": 0.0}})
    assert plain.control is None
    assert plain.system.mode("unconstrained").functions.inputs == 0
    x0 = [plain.initial_state[n] for n in dp.STATE_NAMES]
    simulate(plain.system, x0, "unconstrained", 1.0, 1e-3, 1e-3, "rk4", plain.control)
    assert plain.counters()["actuation_evals"] == 0 and plain.counters()["aba"] > 0

    # On: the control is the PD torque, one entry; the modes take that input.
    kp, kd, target = 35.0, 4.0, 0.7
    pd = dp.make(effects={"stop": {"restitution": 0.0}, "controller": {"kp": kp, "kd": kd, "target": target}})
    assert pd.info["bridge"].actuated_dofs.tolist() == [0]  # theta1's velocity index
    for x in random_states(4, seed=11):
        u = pd.control.input_at("unconstrained", 0.3, x)
        assert np.shape(u) == (1,) and u[0] == pytest.approx(pd_torque(x, kp, kd, target), abs=1e-12)
    assert pd.system.mode("unconstrained").functions.inputs == pd.system.mode("constrained").functions.inputs == 1
    pd.info["bridge"].reset_counters()  # building checked the initial field once, without control
    ex = simulate(pd.system, x0, "unconstrained", 1.0, 1e-3, 1e-3, "rk4", pd.control)
    counts = pd.counters()
    # every dynamics solve adds the control: one actuation term per solve asked for (an ABA
    # call, or one the native library served from its last solve with the same inputs)
    assert counts["actuation_evals"] == counts["aba"] + counts["cache_hits"] and counts["aba"] > 0
    # and it changes the motion: the uncontrolled run ends elsewhere
    uncontrolled = simulate(plain.system, x0, "unconstrained", 1.0, 1e-3, 1e-3, "rk4")
    assert abs(ex.final_state[0] - uncontrolled.final_state[0]) > 0.1


def test_controlled_field_and_stop_force_equal_the_closed_form_with_the_shoulder_torque():
    # M qdd = [u, 0] - C qd - G in the free mode; at the stop (theta2 = theta2d = 0) the stop
    # torque is what keeps qdd_2 = 0: lambda = -(M^-1 ([u, 0] - C qd - G))_2 / (M^-1)_22.
    kp, kd, target = 35.0, 4.0, -0.4
    model = dp.make(P, effects={"controller": {"kp": kp, "kd": kd, "target": target}})
    f = model.system.mode("unconstrained").field
    bridge = model.info["bridge"]
    for x in random_states(6, seed=12):
        q, qd = x[:2], x[2:]
        tau = np.array([pd_torque(x, kp, kd, target), 0.0])
        qdd = np.linalg.solve(mass_matrix(q, **P), tau - coriolis(q, qd, **P) - gravity(q, **P))
        np.testing.assert_allclose(
            f(0.0, x, model.control.input_at("unconstrained", 0.0, x))[2:], qdd, rtol=1e-10, atol=1e-10
        )
    for x in random_states(6, seed=13, at_stop=True):
        x[3] = 0.0
        q, qd = x[:2], x[2:]
        tau = np.array([pd_torque(x, kp, kd, target), 0.0])
        Minv = np.linalg.inv(mass_matrix(q, **P))
        lam = -(Minv[1] @ (tau - coriolis(q, qd, **P) - gravity(q, **P))) / Minv[1, 1]
        forces = bridge.constraint_forces("constrained", x, model.control.input_at("constrained", 0.0, x))
        assert forces["stop"][0] == pytest.approx(lam, abs=1e-9)
        # the constrained field keeps link 2 at the stop and turns the straight pendulum (inertia
        # M_11 at theta2 = 0) under the shoulder torque and gravity
        a = model.system.mode("constrained").field(0.0, x, model.control.input_at("constrained", 0.0, x))
        assert abs(a[3]) < 1e-10
        assert a[2] == pytest.approx((tau[0] - gravity(q, **P)[0]) / mass_matrix(q, **P)[0, 0], rel=1e-10)


def test_controlled_run_balances_energy_with_the_control_and_damping_power():
    # dE/dt = u theta1d - b1 theta1d^2 - b2 theta2d^2 along the unconstrained flow (no stop, so
    # no impact losses). E from the closed form, the work by the trapezoid rule over the stored
    # RK4 steps: the two agree to the rule's O(h^2) error (about 5e-6 J at h = 1e-3 s) at every
    # step, while the controller's own work is near a joule, so a control applied with the wrong
    # sign, to the wrong joint or not at all breaks the balance by orders of magnitude.
    kp, kd, target, b1, b2 = 40.0, 3.0, 0.8, 0.3, 0.2
    model = dp.make(
        P,
        effects={"stop": False, "controller": {"kp": kp, "kd": kd, "target": target}, "damping": {"b1": b1, "b2": b2}},
    )
    x0 = [model.initial_state[n] for n in dp.STATE_NAMES]
    ex = simulate(model.system, x0, "unconstrained", 3.0, 1e-3, 1e-3, "rk4", model.control)
    assert ex.status == "finished" and len(ex.segments) == 1
    seg = ex.segments[0]
    t, x = seg.t, seg.x
    power_u = pd_torque(x.T, kp, kd, target) * x[:, 2]
    power_b = -b1 * x[:, 2] ** 2 - b2 * x[:, 3] ** 2
    half = 0.5 * np.diff(t)  # cumulative trapezoid rule, W(t_k) for every stored step
    work_u = np.concatenate(([0.0], np.cumsum(half * (power_u[1:] + power_u[:-1]))))
    work_b = np.concatenate(([0.0], np.cumsum(half * (power_b[1:] + power_b[:-1]))))
    E = np.array([energy(xi, P) for xi in x])
    residual = E - E[0] - work_u - work_b
    assert np.abs(residual).max() < 2e-5
    assert abs(work_u[-1]) > 0.5 and np.abs(work_u).max() > 0.5
    # the model's own energy (what `legsim run` reports) is the closed form's
    assert model.system.energy("unconstrained", x[-1]) == pytest.approx(E[-1], abs=1e-12)


def test_pd_holds_the_shoulder_where_it_balances_the_hanging_pendulums_gravity():
    # Gravity on, no stop, damping on both joints: the run settles where link 2 hangs vertically
    # (theta1 + theta2 = 0, no torque at the elbow) and the shoulder torque balances gravity,
    # kp (target - theta1) = (m1 + m2) g L1 sin theta1 (link 2's weight acts at the elbow).
    from scipy.optimize import brentq

    kp, kd, target = 60.0, 5.0, 0.8
    model = dp.make(
        P,
        effects={
            "stop": False,
            "controller": {"kp": kp, "kd": kd, "target": target},
            "damping": {"b1": 1.0, "b2": 3.0},
        },
    )
    x0 = [model.initial_state[n] for n in dp.STATE_NAMES]
    ex = simulate(model.system, x0, "unconstrained", 25.0, 5e-3, 1e-3, "rk4", model.control)
    m1, m2, L1, g = P["m1"], P["m2"], P["L1"], P["g"]
    theta = brentq(lambda th: kp * (target - th) - (m1 + m2) * g * L1 * math.sin(th), 0.0, target)
    assert 0.5 < theta < target - 0.1  # gravity pulls it well short of the target
    final = ex.final_state
    assert final[0] == pytest.approx(theta, abs=1e-9)
    assert final[0] + final[1] == pytest.approx(0.0, abs=1e-9)
    assert np.abs(final[2:]).max() < 1e-9


def test_pd_scene_rests_on_the_stop_where_the_pd_balances_the_straight_pendulum():
    # The bundled scene: link 2 lands on the stop (plastic), and the straight pendulum settles in
    # the constrained mode at kp (target - theta1) = ((m1 + m2) L1 + m2 L2) g sin theta1.
    from scipy.optimize import brentq

    from legsim.scene import load_scene

    scene = load_scene("double_pendulum_pd")
    ex = scene.simulate()
    assert ex.status == "finished" and ex.final_mode == "constrained"
    assert ex.transitions[-1].name == "impact_stop"
    p, c = scene.model.info["parameters"], scene.model.info["effects"]["controller"]
    stiffness = ((p["m1"] + p["m2"]) * p["L1"] + p["m2"] * p["L2"]) * p["g"]
    theta = brentq(lambda th: c["kp"] * (c["target"] - th) - stiffness * math.sin(th), 0.0, c["target"])
    assert ex.final_state[0] == pytest.approx(theta, abs=1e-8)
    assert abs(ex.final_state[1]) < 1e-12 and np.abs(ex.final_state[2:]).max() < 1e-8
    assert ex.counters["actuation_evals"] > 0
    # the stop holds it there: its force is positive at rest
    lam = scene.model.info["bridge"].constraint_forces(
        "constrained", ex.final_state, scene.model.control.input_at("constrained", 0.0, ex.final_state)
    )
    assert lam["stop"][0] > 0.0


@pytest.mark.parametrize(
    "override, message",
    [
        ("effects.controller.kp=-1", "effects.controller.kp: -1.0 is out of range, allowed: float in [0, inf)"),
        ("effects.controller.kd=-0.5", "effects.controller.kd: -0.5 is out of range, allowed: float in [0, inf)"),
        (
            "effects.controller.target=4",
            "effects.controller.target: 4.0 is out of range, allowed: float in [-3.14159, 3.14159]",
        ),
        ('effects.controller.kp="x"', "effects.controller.kp: expected a number"),
        ("effects.controller.kx=1", "effects.controller: unknown parameter(s) ['kx']; allowed: ['kd', 'kp', 'target']"),
        ("effects.controller=1", "effects.controller: expected true, false or a table of parameters"),
    ],
)
def test_bad_controller_parameters_are_scene_errors_naming_the_field(override, message):
    from legsim.scene import load_scene

    with pytest.raises(SceneError) as err:
        load_scene("double_pendulum_pd", overrides=[override])
    assert message in str(err.value) and "double_pendulum_pd.toml" in str(err.value)
