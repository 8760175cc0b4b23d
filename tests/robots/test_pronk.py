"""The pronking runner of paper 000 Section V-C: Newton-Euler closed form of the stance fields,
energy conservation through touchdowns and liftoffs at the method's order, simultaneous
touchdowns of the symmetric pronk, the pitched variants, effect switching."""

import math
import os

import numpy as np
import pytest
from legsim.robots import pronk, slip

from legsim import simulate
from legsim.graph import reachable_modes

FULL = os.environ.get("LEGSIM_FULL") == "1"


def skip_unless_full(request):
    """Long sweeps run with LEGSIM_FULL=1 or -m slow; their short forms always run."""
    if not FULL and "slow" not in (request.config.getoption("markexpr") or ""):
        pytest.skip("long sweep: set LEGSIM_FULL=1 or select -m slow")


PAPER = dict(m=1.0, I=1.0, k=30.0, l=1.0, d=1.0, g=9.81, psi=math.pi / 5)


def newton_euler(x, legs, p=PAPER, b=0.0):
    """Hand-derived stance field: body (x, z, theta) with theta about +y (the body axis is
    (cos theta, -sin theta) in the (x, z) plane), legs pushing k (l - r) - b dr/dt along hip - foot."""
    X, Z, th, xd, zd, thd = x[:6]
    axis = np.array([math.cos(th), -math.sin(th)])
    axis_rate = thd * np.array([-math.sin(th), -math.cos(th)])
    force = np.array([0.0, -p["m"] * p["g"]])
    torque = 0.0
    for side, foot_x in zip(legs, x[6:], strict=False):
        sign = -1.0 if side == "left" else 1.0
        arm = sign * p["d"] / 2 * axis
        hip = np.array([X, Z]) + arm
        hip_v = np.array([xd, zd]) + sign * p["d"] / 2 * axis_rate
        rv = hip - np.array([foot_x, 0.0])
        r = np.linalg.norm(rv)
        u = rv / r
        f = (p["k"] * (p["l"] - r) - b * (u @ hip_v)) * u
        force += f
        torque += arm[1] * f[0] - arm[0] * f[1]  # y component of arm x f in the (x, z) plane
    return np.array([xd, zd, thd, force[0] / p["m"], force[1] / p["m"], torque / p["I"]])


def energy_error(system, ex, E0):
    """Largest |E - E0| over every stored point of the execution (J)."""
    worst = 0.0
    for seg in ex.segments:
        for x in seg.x:
            worst = max(worst, abs(system.energy(seg.mode, x) - E0))
    return worst


CASES = {  # name: (initial state, t_final): every case passes through touchdowns (and liftoffs)
    "symmetric": (pronk.INITIAL_STATE, 2.0),
    "pitched": (pronk.PITCHED_STATE, 0.45),  # later the soft legs let the body sink to the ground
    "pitch_rate": (pronk.PITCH_RATE_STATE, 0.7),
}


def test_stance_fields_equal_newton_euler():
    params = dict(m=1.4, I=0.6, k=42.0, l=0.9, d=0.8, g=9.81, psi=0.5)
    model = pronk.make(params)
    rng = np.random.default_rng(0)
    for mode, legs in [("aerial", []), ("left", ["left"]), ("right", ["right"]), ("both", ["left", "right"])]:
        f = model.system.mode(mode).field
        for _ in range(5):
            x = np.concatenate(
                [[0.3, 0.8, rng.uniform(-0.6, 0.6)], rng.normal(size=3), 0.3 + rng.uniform(-0.5, 0.5, len(legs))]
            )
            expected = np.concatenate([newton_euler(x, legs, params), np.zeros(len(legs))])
            np.testing.assert_allclose(f(0.0, x, None), expected, rtol=0, atol=1e-12)
    damped = pronk.make(params, {"damping": {"b": 0.7}})
    x = np.array([0.1, 0.7, 0.2, 1.0, -2.0, 0.5, 0.4, 1.1])
    np.testing.assert_allclose(
        damped.system.mode("both").field(0.0, x, None)[:6],
        newton_euler(x, ["left", "right"], params, b=0.7),
        atol=1e-12,
    )


def test_flight_legs_and_guards_follow_the_paper_geometry():
    model = pronk.make()
    system = model.system
    # theta = 0: both feet l cos(psi) below the hips, so both touchdown guards vanish at z = cos(psi)
    x = pronk.state({"z": math.cos(math.pi / 5), "zd": -1.0})
    assert [tr.name for tr in system.outgoing("aerial")] == ["touchdown_left", "touchdown_right"]
    np.testing.assert_allclose(system.guard_values("aerial", x), [0.0, 0.0], atol=1e-15)
    # theta0 = -0.4 lifts the nose: the left (rear) foot is the lower one
    feet = model.info["bridge"].foot_positions("aerial", pronk.state(pronk.PITCHED_STATE))
    assert feet["left"][1] < feet["right"][1]
    assert feet["left"][1] == pytest.approx(1.1 - 0.5 * math.sin(0.4) - math.cos(math.pi / 5 + 0.4), abs=1e-12)


@pytest.mark.parametrize("case", sorted(CASES))
def test_energy_is_conserved_through_touchdowns_and_liftoffs(case):
    state, t_final = CASES[case]
    model = pronk.make()
    x0 = pronk.state(state)
    E0 = model.system.energy("aerial", x0)
    ex = simulate(model.system, x0, "aerial", t_final, 1e-3, 1e-2)
    assert ex.status == "finished"
    assert len(ex.transitions) >= 2 and {"left", "right", "both"} & set(ex.mode_sequence)
    assert energy_error(model.system, ex, E0) < 1e-8  # RK4 at h = 1e-3: ~1e-9 J over the run
    # A transition keeps q and v and a leg changes state at its rest length, so energy is
    # continuous through it; the bound of the issue is O(eps^2) at the paper's eps = 1e-2.
    for tr in ex.transitions:
        dE = model.system.energy(tr.target, tr.state_after) - model.system.energy(tr.source, tr.state_before)
        assert abs(dE) <= 1e-2**2 * 1e-6


@pytest.mark.parametrize(
    "method,order,hs",
    [("euler", 1, (1e-3, 5e-4, 2.5e-4)), ("rk2", 2, (4e-3, 2e-3, 1e-3)), ("rk4", 4, (1.6e-2, 8e-3, 4e-3))],
)
@pytest.mark.parametrize("case", ["symmetric", "pitched"])
def test_energy_drift_shrinks_at_the_method_order(case, method, order, hs):
    state, t_final = CASES[case]
    model = pronk.make()
    x0 = pronk.state(state)
    E0 = model.system.energy("aerial", x0)
    errs = []
    for h in hs:
        ex = simulate(model.system, x0, "aerial", t_final, h, 1e-2, method=method)
        assert ex.status == "finished"
        errs.append(energy_error(model.system, ex, E0))
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    # The strips cost no energy (held state, continuous resets), so the drift is the method's
    # own: slope >= order (rk2 drifts faster than its order over the symmetric hops).
    assert slope > order - 0.25, (errs, slope)


def test_symmetric_pronk_crosses_both_touchdown_guards_at_once():
    eps = 1e-2
    model = pronk.make()
    ex = simulate(model.system, pronk.state(), "aerial", 2.0, 1e-3, eps)
    seq = ex.mode_sequence
    assert seq[:3] in (["aerial", "left", "both"], ["aerial", "right", "both"])
    first, second = ex.transitions[0], ex.transitions[1]
    # one stance lasts only while the second guard's strip is crossed: within a few eps
    assert second.exit_time - first.time < 3 * eps
    assert first.state_before[2] == 0.0 and second.state_before[1] == pytest.approx(first.state_before[1], abs=1e-12)
    theta = np.concatenate([seg.x[:, 2] for seg in ex.segments])
    assert np.abs(theta).max() < 1e-11  # rounding only: theta = 0 is invariant
    assert [tr.name.split("_")[0] for tr in ex.transitions] == ["touchdown", "touchdown", "liftoff", "liftoff"] * 2


def limit_distance(eps, h, T=0.5):
    """Distance at time T (mid-stance) between the relaxed symmetric pronk and its eps -> 0 limit,
    the SLIP with the two legs merged (paper 000: the pronk is a SLIP gait) run with eps = 1e-9."""
    ref = simulate(slip.make().system, slip.state(), "flight", T, h, 1e-9).final_state
    x = simulate(pronk.make().system, pronk.state(), "aerial", T, h, eps).final_state
    return float(np.linalg.norm(x[[0, 1, 3, 4]] - ref[:4]))


def test_halving_eps_halves_the_distance_to_the_limit():
    # h well below eps so that the landing depth (up to |dz/dt| h) is small against eps
    h = 2.5e-4
    d = [limit_distance(eps, h) for eps in (1e-2, 5e-3, 2.5e-3)]
    ratios = np.array(d[:-1]) / np.array(d[1:])
    assert np.all(np.abs(ratios - 2.0) < 0.2), (d, ratios)


@pytest.mark.slow
def test_halving_eps_halves_the_distance_to_the_limit_full(request):
    skip_unless_full(request)
    h = 5e-5
    d = [limit_distance(eps, h) for eps in (2e-2, 1e-2, 5e-3, 2.5e-3, 1.25e-3)]
    ratios = np.array(d[:-1]) / np.array(d[1:])
    assert np.all(np.abs(ratios - 2.0) < 0.06), (d, ratios)


@pytest.mark.parametrize("state", [pronk.PITCHED_STATE, pronk.PITCH_RATE_STATE])
def test_pitched_runner_passes_through_left_stance_then_both(state):
    model = pronk.make()
    ex = simulate(model.system, pronk.state(state), "aerial", 0.45, 1e-3, 1e-2)
    assert ex.mode_sequence[:3] == ["aerial", "left", "both"]
    # separately: the left stance lasts many strips long
    assert ex.transitions[1].time - ex.transitions[0].exit_time > 5e-2


def test_legs_and_damping_are_built_only_when_asked():
    assert sorted(reachable_modes(pronk.make().system, "aerial")) == ["aerial", "both", "left", "right"]
    left_only = pronk.make(effects={"right_leg": False})
    assert sorted(reachable_modes(left_only.system, "aerial")) == ["aerial", "left"]
    assert left_only.system.mode("left").names == (*pronk.STATE_NAMES, "left_foot_x")
    none = pronk.make(effects={"left_leg": False, "right_leg": False})
    assert reachable_modes(none.system, "aerial") == ["aerial"] and none.system.outgoing("aerial") == ()

    # flight computes no leg Jacobian, no spring force, no constraint solve
    model = pronk.make()
    ex = simulate(model.system, pronk.state(), "aerial", 0.2, 1e-3, 1e-2)
    assert ex.transitions == []
    c = model.counters()
    assert c["aba"] > 0 and c["jacobians"] == c["spring_forces"] == c["kkt"] == c["damping_evals"] == 0
    # stance without damping: spring forces, no damping term
    simulate(model.system, pronk.state(), "aerial", 0.5, 1e-3, 1e-2)
    c = model.counters()
    assert c["spring_forces"] > 0 and c["damping_evals"] == 0
    # with damping: one damping term per spring force, and energy is lost in stance only
    damped = pronk.make(effects={"damping": {"b": 0.5}})
    x0 = pronk.state()
    ex = simulate(damped.system, x0, "aerial", 1.0, 1e-3, 1e-2)
    c = damped.counters()
    assert c["damping_evals"] == c["spring_forces"] > 0
    E = [damped.system.energy(s.mode, x) for s in ex.segments for x in s.x]
    assert np.all(np.diff(E) < 1e-9) and E[-1] < E[0] - 0.1


def test_a_runner_that_falls_ends_the_run_instead_of_flying_through_the_ground():
    # theta0 = +0.1 (nose down): after the first stance both legs lift off low and, swung to
    # their flight angle, their feet are about 0.24 m below the ground, rising with the body.
    # The body turns down before they come out: a foot below the ground that descends is past
    # its touchdown guard by its depth, so no step lands in the strip and the run ends with an
    # honest status (keeping the execution) instead of pinning a buried foot, which would add
    # spring energy.
    model = pronk.make()
    bridge = model.info["bridge"]
    ex = simulate(model.system, pronk.state({"theta": 0.1}), "aerial", 2.0, 1e-3, 1e-2)
    assert ex.status == "halving_exhausted" and "the guard of transition touchdown_left goes from" in ex.message
    assert "It jumps there" in ex.message and "foot is below the ground while the body rises" in ex.message
    assert [tr.name for tr in ex.transitions][-2:] == ["liftoff_right", "liftoff_left"]
    assert bridge.foot_positions(ex.final_mode, ex.final_state)["left"][1] < -0.2
    for tr in ex.transitions:
        assert model.system.energy(tr.target, tr.state_after) == pytest.approx(
            model.system.energy(tr.source, tr.state_before), abs=1e-10
        )
    # the guard: a buried foot is in flight while it rises, past by its depth once it descends
    index = [tr.name for tr in model.system.outgoing("aerial")].index("touchdown_left")

    def guard(x):
        return model.system.guard_values("aerial", x)[index]

    buried = math.cos(math.pi / 5) - 0.1
    assert guard(pronk.state({"z": buried, "zd": 1.0})) == pytest.approx(1.0)
    assert guard(pronk.state({"z": buried, "zd": -1e-3})) == pytest.approx(-0.1)
    assert guard(pronk.state({"z": 1.0, "zd": -2.0})) == pytest.approx(1.0 - math.cos(math.pi / 5))


def test_a_stance_initial_state_is_accepted_although_its_legs_are_not_at_rest_length():
    # HybridSystem.check_state tries every reset on the initial state, legs compressed or not
    model = pronk.make()
    x = np.array([0.0, 0.6, 0.1, 1.0, 0.0, 0.0, -0.6, 0.4])  # both legs compressed
    model.system.check_state("both", x)
    ex = simulate(model.system, x, "both", 0.25, 1e-3, 1e-2)
    assert ex.status == "finished" and ex.mode_sequence == ["both"]


def test_a_leg_swung_into_the_ground_at_liftoff_while_moving_down_is_a_fall():
    # The paper's apex with psi = pi/5 is not periodic: the third stance runs backwards and, at
    # the left leg's liftoff, its foot swung forward to the flight angle would be 0.78 m below
    # the ground and descending. That is a fall (model_breakdown), not a scuff: a foot below the
    # ground but rising (every symmetric gait's liftoff, within rounding) stays in flight.
    model = pronk.make()
    ex = simulate(model.system, pronk.state(), "aerial", 3.0, 1e-3, 1e-2)
    assert ex.status == "model_breakdown" and ex.final_mode == "both"
    assert "a foot below the ground and moving down after its liftoff" in ex.message
    bridge = model.info["bridge"]
    x = ex.final_state
    # past liftoff the model functions say so: every guard of the mode is nan there
    flight_foot = bridge.frame_positions(x[:3], ["left_foot"])["left_foot"]
    assert flight_foot[1] < -0.5
    # at the last state kept, the left leg is still (barely) compressed: the fall is detected
    # within the step that extends it past its rest length
    assert 0.0 < bridge.leg_forces("both", x)["left"] < 1.0
    # The message measures the state it stopped at: the lowest hip (the body's axis is
    # (cos theta, -sin theta), the hips d/2 behind and ahead of its centre) and the left foot
    # swung forward, with their heights as printed.
    hips = {"left": x[1] + PAPER["d"] / 2 * math.sin(x[2]), "right": x[1] - PAPER["d"] / 2 * math.sin(x[2])}
    lowest = min(hips, key=hips.get)
    assert f"lowest hip: leg '{lowest}', {hips[lowest]:.3g} m above the ground" in ex.message
    assert f"leg 'left': its foot swung to its flight angle at liftoff, {-flight_foot[1]:.3g} m below" in ex.message
