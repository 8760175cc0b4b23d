"""The pronk hopper (robots/pronk_hopper.py) and Raibert's control of it (robots/raibert_pronk.py):
uncontrolled it is the bridge's pronk; its hip torques obey the angular momentum and power
balances of a massless leg; controlled it runs 100 hops at a commanded speed, the SLIP hopper's
gait when its pitch is 0, and its stance hips bring a pitched body back to level."""

import math

import numpy as np
import pytest
from legsim.robots import pronk, pronk_hopper, raibert_pronk

from legsim import simulate
from legsim.errors import SceneError
from legsim.orbits import find_orbit
from legsim.scene import load_scene
from legsim.scene.orbit import problem_from_scene

HOPPER = pronk_hopper.PronkHopper(m=1.0, I=1.0, k=30.0, l=1.0, d=1.0, g=9.81)


def test_without_control_the_hopper_is_the_bridge_pronk():
    """Legs at the pronk's psi, no control, a pitched start (the legs land and leave one at a
    time): the same four transitions at the same times and body states as the bridge pronk,
    built independently with Pinocchio. The run ends after both liftoffs: the pronk then swings
    its legs back to psi, the uncontrolled hopper leaves them at their stance angles, and from
    this start both runs soon end with the body low (the pitched pronk is not a gait)."""
    psi = math.pi / 5
    start = {**pronk_hopper.INITIAL_STATE, "theta": 0.1, "psi_left": psi, "psi_right": psi}
    x0 = np.array([start[name] for name in pronk_hopper.state_names(())])
    mine = simulate(HOPPER.system(), x0, "aerial", 0.62, 1e-3, 1e-6)
    theirs = simulate(pronk.make().system, pronk.state({"theta": 0.1}), "aerial", 0.62, 1e-3, 1e-6)
    assert mine.status == theirs.status == "finished"
    names = ["touchdown_right", "touchdown_left", "liftoff_right", "liftoff_left"]
    assert [tr.name for tr in mine.transitions] == [tr.name for tr in theirs.transitions] == names
    for a, b in zip(mine.transitions, theirs.transitions, strict=True):
        assert a.source == b.source and a.target == b.target
        assert a.time == pytest.approx(b.time, abs=1e-9)
        np.testing.assert_allclose(a.state_after[:6], b.state_after[:6], atol=1e-9)


def random_single_stance(rng: np.random.Generator) -> np.ndarray:
    """A state of mode ``left``: (x, z, theta, xd, zd, thetad, psi_right, left_foot_x)."""
    return np.array([*rng.uniform(-0.3, 0.3, 1), 0.8, *rng.uniform(-0.4, 0.4, 5), rng.uniform(-0.5, 0.5)])


def test_hip_torques_keep_the_massless_legs_balances():
    """In single stance with any hip torques and swing rates: the angular momentum about the foot
    changes by gravity's moment alone (the massless leg passes the ground force through the
    foot), and the energy changes by the hip torque's power on body and leg, torque times
    (thetad + the leg's forward swing rate) (closed forms)."""
    rng = np.random.default_rng(3)
    field = HOPPER.system().mode("left").field
    for _ in range(20):
        x, u = random_single_stance(rng), rng.uniform(-5.0, 5.0, 4)
        dx = field(0.0, x, u)
        from_foot = x[:2] - np.array([x[7], 0.0])
        # d/dt [I thetad + m (r x v)_y] with (a x b)_y = a_z b_x - a_x b_z
        momentum_rate = HOPPER.I * dx[5] + HOPPER.m * (from_foot[1] * dx[3] - from_foot[0] * dx[4])
        gravity_moment = from_foot[0] * HOPPER.m * HOPPER.g
        assert momentum_rate == pytest.approx(gravity_moment, abs=1e-12)
        hip, hip_velocity = HOPPER.hip("left", x)
        along = hip - np.array([x[7], 0.0])
        # The leg's world angle from the downward vertical, forward: atan2(foot_x - hip_x, hip_z).
        swing = (along[0] * hip_velocity[1] - along[1] * hip_velocity[0]) / float(along @ along)
        energy_rate = np.gradient([HOPPER.energy("left", x + s * dx) for s in (-1e-6, 0.0, 1e-6)], 1e-6)[1]
        assert energy_rate == pytest.approx(u[2] * (x[5] + swing), abs=1e-6)


@pytest.fixture(scope="module")
def raibert_run():
    scene = load_scene("pronk_raibert")
    return scene, scene.simulate()


def hops(execution) -> list:
    """Each flight's end: the first touchdown out of ``aerial``."""
    return [tr for tr in execution.transitions if tr.source == "aerial"]


def test_raibert_pronk_tracks_the_commanded_speed_over_100_hops(raibert_run):
    """The scene: from 1 m/s to the commanded 1.5 m/s; from the 20th hop on every flight's speed
    within 5% of it, the pitch 0 to rounding, the energy conserved (the servo does no work at
    pitch 0). Level, the pronk is a SLIP on both legs' springs (2 x 250 N/m = the SLIP
    hopper's 500 N/m, same mass, start and gains): it settles at the SLIP hopper's speed."""
    scene, ex = raibert_run
    assert ex.status == "finished" and not ex.warnings
    assert ex.counters["python_steps"] == 0 and ex.counters["compiled_steps"] == ex.counters["steps"]
    touchdowns = hops(ex)
    assert len(touchdowns) >= 100
    speeds = np.array([tr.state_before[3] for tr in touchdowns])
    assert abs(speeds[0] - 1.5) > 0.3 * 1.5 and np.all(np.abs(speeds[20:] / 1.5 - 1.0) < 0.05)
    assert max(float(np.max(np.abs(seg.x[:, 2]))) for seg in ex.segments) < 1e-7
    energy = scene.model.system.energy
    initial = energy("aerial", scene.initial_state)
    assert max(abs(energy("aerial", tr.state_before[:8]) - initial) for tr in touchdowns) < 1e-6 * initial
    slip = load_scene("slip_raibert", ["integrator.t_final=15"]).simulate()
    slip_speed = [tr.state_before[3] for tr in slip.transitions if tr.name == "touchdown"][-1]
    assert speeds[-1] == pytest.approx(slip_speed, abs=1e-6)


def test_raibert_pronk_measures_each_legs_stance(raibert_run):
    """Each leg's memory follows the run's state: its touchdown notes the time it enters the
    stance, its liftoff sets its T_s to that stance's duration, the difference of the two entry
    times to the last bit, and clears the touchdown time; the leg's memory changes at its own
    transitions only."""
    _, ex = raibert_run
    assert ex.state_names["both"][8:] == raibert_pronk.MEMORY
    for i, leg in enumerate(pronk_hopper.LEGS):
        touchdown = None
        for tr in ex.transitions[:40]:
            memory_before, memory_after = tr.state_before[8:], tr.state_after[8:]
            if tr.name == f"touchdown_{leg}":
                touchdown = tr
                assert memory_after[[2 + i, 4 + i]].tolist() == [tr.exit_time, 1.0]
            elif tr.name == f"liftoff_{leg}":
                assert memory_after[[i, 2 + i, 4 + i]].tolist() == [tr.exit_time - touchdown.exit_time, 0.0, 0.0]
            else:
                assert memory_after[[i, 2 + i, 4 + i]].tolist() == memory_before[[i, 2 + i, 4 + i]].tolist()


def law_input(law, mode, t, x):
    """The law's input in ``mode`` at a stored state x (the plant's 8 coordinates, then the memory)."""
    u = np.zeros(law.inputs)
    law.control(float(t), np.ascontiguousarray(x[:8]), np.ascontiguousarray(x[8:]), law.params_for(mode), u)
    return u


def pitch_at_touchdowns(*overrides: str) -> np.ndarray:
    ex = load_scene("pronk_raibert", ["integrator.t_final=4", "initial.state.theta=0.01", *overrides]).simulate()
    assert ex.status == "finished" and not ex.warnings
    return np.array([abs(tr.state_before[2]) for tr in hops(ex)])


def test_stance_hips_level_a_pitched_body():
    """From a pitch of 0.01 rad the stance hips' servo shrinks the pitch at each touchdown by
    more than half a hop; without it the pitch grows past 0.1 rad within 4 s."""
    servoed = pitch_at_touchdowns()
    assert np.all(servoed[1:] < 0.5 * servoed[:-1])
    free = pitch_at_touchdowns("controller.parameters.kp_attitude=0", "controller.parameters.kd_attitude=0")
    assert np.max(free) > 0.1


def test_raibert_pronk_drives_only_the_pronk_hopper():
    with pytest.raises(SceneError, match=r"raibert_pronk.*pronk_hopper"):
        load_scene("pronk_raibert", ["robot.name=pronk"])


#: The runs' own integrator for the search (the scenes' [orbit.integrator] is finer): the kink
#: in the pitch shows at this map's resolution.
RUN_SETTINGS = 'orbit.integrator={method="rk4", h=1e-3, eps=1e-7, landing="aim"}'


def scene_orbit(name: str):
    settings = problem_from_scene(load_scene(name, [RUN_SETTINGS]))
    return find_orbit(settings.problem, settings.guess, **settings.solver).raise_for_status()


def leading(multipliers: np.ndarray) -> complex:
    """The multiplier of largest modulus other than the energy's trivial 1."""
    return max((mu for mu in np.asarray(multipliers, dtype=complex) if abs(mu - 1) > 1e-3), key=abs)


def test_raibert_pronk_gait_is_the_slip_hoppers_with_a_contracting_pitch():
    """``legsim orbit pronk_raibert`` at the run's own rk4 steps: the level gait is the SLIP
    hopper's (independent model, ``slip_raibert``): the same apex and period, and the SLIP's
    multipliers are among the pronk's. In the pitch the return map has a small kink: the
    stencil's returns on either side of it land the left or the right foot first (and the
    servo's torque limit clips near touchdown and liftoff once the body pitches), so the
    multipliers do not decide stability; the piecewise-linear derivative's two pieces (one per
    touchdown order) do: stable, by a common quadratic Lyapunov function. Both sides' leading
    pitch multipliers agree within 1% and are far inside the unit circle, and a run started on
    the gait with a pitch sheds it at that rate."""
    pronk_gait, slip_gait = scene_orbit("pronk_raibert"), scene_orbit("slip_raibert")
    names = pronk_gait.state_names
    # Both at eps = 1e-7: the pronk crosses four strips a hop, the SLIP two, and each crossing
    # moves the return by O(eps), so the two gaits agree to a few eps.
    for name in ("z", "xd"):
        assert pronk_gait.fixed_point[names.index(name)] == pytest.approx(
            slip_gait.fixed_point[slip_gait.state_names.index(name)], abs=1e-6
        )
    assert pronk_gait.period == pytest.approx(slip_gait.period, abs=1e-6)
    pronk_mu, slip_mu = np.asarray(pronk_gait.multipliers), np.asarray(slip_gait.multipliers)
    for mu in slip_mu[np.abs(slip_mu) > 1e-3]:
        assert np.min(np.abs(pronk_mu - mu)) < 1e-5
    assert pronk_gait.differentiable is False and "theta" in pronk_gait.kinked_coordinates
    verdict = pronk_gait.piecewise
    assert pronk_gait.stable is True and verdict.kind == "stable" and verdict.details["length"] == 1
    assert verdict.details["orders"][0][:2] == ["touchdown_left", "touchdown_right"]
    assert max(verdict.details["piece_radii"]) < 0.3
    forward, backward = leading(pronk_gait.multipliers_forward), leading(pronk_gait.multipliers_backward)
    assert forward.real < 0 and backward.real < 0 and abs(forward) < 0.3 and abs(backward) < 0.3
    assert forward.real == pytest.approx(backward.real, rel=0.01)
    gait = {name: float(value) for name, value in zip(names, pronk_gait.fixed_point, strict=True)}
    start = [f"initial.state.{name}={value!r}" for name, value in gait.items() if name != "theta"]
    stance_time = float(pronk_gait.memory[0])
    ex = load_scene(
        "pronk_raibert",
        [
            *start,
            "initial.state.theta=0.001",
            f"controller.parameters.stance_time={stance_time!r}",
            "integrator.t_final=4.5",
        ],
    ).simulate()
    pitches = np.array([tr.state_before[2] for tr in hops(ex)])
    # By the 6th hop the other pitch modes (|mu| < 0.1) have decayed 200-fold relative to it.
    np.testing.assert_allclose(pitches[5:7] / pitches[4:6], (forward.real + backward.real) / 2, rtol=0.01)


def test_the_pitch_servo_never_makes_the_ground_pull_on_a_foot():
    """From a pitch of 0.01 rad the servo's torques are largest where a leg's spring pushes least
    (at touchdown and liftoff): each leg's normal force k (l - r) n_z + (torque / r) n_x stays at
    least half the spring's push k (l - r) n_z, at every stored state of every stance."""
    scene = load_scene("pronk_raibert", ["integrator.t_final=4", "initial.state.theta=0.01"])
    ex, law, hopper = scene.simulate(), scene.control, scene.model.info["pronk_hopper"]
    checked = 0
    for seg in ex.segments:
        stance = pronk_hopper.MODES[seg.mode]
        names = pronk_hopper.state_names(stance)
        for t, x in zip(seg.t, seg.x, strict=True):
            u = law_input(law, seg.mode, t, x)
            for leg in stance:
                n, r, _ = hopper.leg_in_stance(leg, x, x[names.index(f"{leg}_foot_x")])
                push = hopper.k * (hopper.l - r) * n[1]
                torque = u[2 + pronk_hopper.LEGS.index(leg)]
                assert push + torque / r * n[0] >= 0.5 * push - 1e-9
                checked += abs(torque) > 0.0
    assert checked > 100


def test_a_foot_landing_below_the_ground_is_a_model_breakdown():
    """A touchdown whose foot is already below the ground (the guard's rate leaves the leg's
    swing out) is refused rather than pinned with its spring compressed: its image is nan, past
    the model's range, and a run that reaches it ends in a model breakdown there."""
    system = HOPPER.system()
    transition = next(tr for tr in system.transitions if tr.name == "touchdown_left" and tr.source == "aerial")
    x = np.array([0.0, 0.7, 0.0, 1.0, -1.0, 0.0, 0.3, 0.3])  # the foot 0.7 - cos(0.3) = -0.255 m
    assert np.isnan(transition.reset(x)).any() and system.mode("aerial").functions.nan_breaks
    # Rising with both feet 0.255 m under the ground: at the apex the feet's rate turns negative.
    rising = np.array([0.0, 0.7, 0.0, 0.0, 1.0, 0.0, 0.3, 0.3])
    ex = simulate(system, rising, "aerial", 1.0, 1e-3, 1e-6)
    assert ex.status == "model_breakdown" and "reset of transition touchdown_" in ex.message and ex.t_end < 0.2
    assert "a flight leg lands with its foot below the ground" in ex.message
