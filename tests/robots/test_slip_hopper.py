"""The SLIP hopper (robots/slip_hopper.py) and Raibert's foot placement for it
(``raibert_slip``, raibert.slip_law): uncontrolled it is the bridge's SLIP; controlled it runs 100
hops and tracks the commanded speed, conserving energy, on a stable periodic gait."""

import math

import numpy as np
import pytest
from legsim.robots import raibert, slip, slip_hopper

from legsim import simulate
from legsim.errors import SceneError
from legsim.orbits import OrbitProblem, Section, find_orbit
from legsim.scene import load_scene


def test_without_control_the_hopper_is_the_bridge_slip():
    """Leg angle fixed (u = 0): the first touchdown at the ballistic closed form, the stance and
    the liftoff at the bridge SLIP's times and states (the same flow, built independently; after
    liftoff the SLIP swings its leg back to psi, the uncontrolled hopper leaves it behind)."""
    hopper = slip_hopper.make_system(m=1.0, k=60.0, l=1.0, g=9.81)
    psi = math.pi / 5
    mine = simulate(hopper, np.array([0.0, 1.1, psi, 3.4, 0.0]), "flight", 1.0, 1e-3, 1e-6)
    theirs = simulate(slip.make().system, slip.state(), "flight", 1.0, 1e-3, 1e-6)
    assert mine.status == theirs.status == "finished"
    assert [tr.name for tr in mine.transitions] == ["touchdown", "liftoff"]
    assert [tr.name for tr in theirs.transitions] == ["touchdown_leg", "liftoff_leg"]
    assert mine.transitions[0].time == pytest.approx(math.sqrt(2 * (1.1 - math.cos(psi)) / 9.81), abs=1e-6)
    for a, b in zip(mine.transitions, theirs.transitions, strict=True):
        assert a.time == pytest.approx(b.time, abs=1e-9)
    np.testing.assert_allclose(mine.transitions[0].state_after, theirs.transitions[0].state_after, atol=1e-9)
    np.testing.assert_allclose(
        mine.transitions[1].state_after[[0, 1, 3, 4]], theirs.transitions[1].state_after, atol=1e-9
    )


def flight_input(law, stance_time):
    """A plain control ``u(t, x)``: the law's flight input with its stance time held at
    ``stance_time`` (s), the compiled function evaluated from Python."""
    p = law.params_for("flight")
    memory = np.array([stance_time, 0.0, 0.0])

    def control(t, x):
        u = np.zeros(1)
        law.control(float(t), np.ascontiguousarray(x[:5], dtype=float), memory, p, u)
        return u

    return control


def assert_tracks_the_commanded_speed(scene, ex):
    """The slip_raibert scene's run ``ex``: 100 hops or more, from 1 m/s to within 5% of the
    commanded speed from the 20th hop on, energy conserved to 1e-6."""
    assert ex.status == "finished" and not ex.warnings
    touchdowns = [tr for tr in ex.transitions if tr.name == "touchdown"]
    assert len(touchdowns) >= 100
    speed = scene.controller.params_for("flight")[raibert.C_SPEED]
    errors = np.array([abs(tr.state_before[3] - speed) / speed for tr in touchdowns])
    assert errors[0] > 0.3 and np.all(errors[20:] < 0.05)
    energy = scene.model.system.energy
    initial = energy("flight", scene.initial_state)
    assert max(abs(energy("flight", tr.state_before[:5]) - initial) for tr in touchdowns) < 1e-6 * initial


def test_raibert_slip_tracks_the_commanded_speed_over_100_hops():
    """The scene: from 1 m/s to the commanded 1.5 m/s; from the 20th hop on every flight's speed
    within 5% of it (proportional foot placement leaves a steady error), energy conserved; every
    step compiled."""
    scene = load_scene("slip_raibert")
    ex = scene.simulate()
    assert_tracks_the_commanded_speed(scene, ex)
    assert ex.counters["python_steps"] == 0 and ex.counters["compiled_steps"] == ex.counters["steps"] > 60_000


def test_raibert_slip_measures_each_stance_in_its_memory():
    """The memory (T_s, t_touchdown, stance) follows the run's state: each touchdown's image notes
    the time it enters the stance; each liftoff's sets T_s to that stance's duration, the
    difference of the two entry times to the last bit, and clears the touchdown time; the first
    flight keeps the initial T_s."""
    scene = load_scene("slip_raibert", ["integrator.t_final=3"])
    ex = scene.simulate()
    assert ex.state_names["flight"][-3:] == raibert.SLIP_MEMORY and ex.state_units["flight"][-3:] == ("s", "s", "")
    initial = scene.controller.initial_memory[0]
    assert initial == pytest.approx(math.pi * math.sqrt(1.0 / 500.0)) and ex.segments[0].x[-1, 5] == initial
    pairs = list(zip(ex.transitions[0::2], ex.transitions[1::2], strict=False))
    assert len(pairs) >= 4
    for touchdown, liftoff in pairs:
        assert (touchdown.name, liftoff.name) == ("touchdown", "liftoff")
        assert touchdown.state_after[5:].tolist() == [touchdown.state_before[5], touchdown.exit_time, 1.0]
        assert liftoff.state_after[5:].tolist() == [liftoff.exit_time - touchdown.exit_time, 0.0, 0.0]


def test_raibert_slip_needs_the_hopper():
    with pytest.raises(SceneError, match="slip_hopper"):
        raibert.SLIP.build(slip.make(), {})


def test_raibert_slip_gait_is_a_stable_periodic_orbit():
    """`legsim.orbits` on the controlled hopper (apex section, the scene's energy): the periodic
    gait's apex speed is the speed the 100-hop run settles at, its period the run's hop time,
    and its multipliers, besides the energy's 1, lie inside the unit circle. The controller's
    stance time T_s is held at its value on the gait (there the orbit is the closed loop's; the
    multipliers are those of the foot placement with T_s frozen)."""
    scene = load_scene("slip_raibert")
    ex = scene.simulate()
    touchdowns = [tr for tr in ex.transitions if tr.name == "touchdown"]
    liftoffs = [tr for tr in ex.transitions if tr.name == "liftoff"]
    # The gait's T_s is the run's last stance.
    stance_time = liftoffs[-1].exit_time - touchdowns[-1].exit_time
    problem = OrbitProblem(
        scene.model.system,
        Section.level("flight", "zd", 0.0, direction=-1),
        1e-3,
        1e-4,
        "rk4",
        t_max=2.0,
        control=flight_input(scene.controller, stance_time),
        cyclic=["x"],
        energy=scene.model.system.energy("flight", scene.initial_state),
        trivial_multipliers=1,
    )
    orbit = find_orbit(problem, {"x": 0.0, "z": 1.2, "psi": 0.1, "xd": 1.4, "zd": 0.0})
    assert orbit.converged and orbit.stable
    assert orbit.fixed_point[3] == pytest.approx(touchdowns[-1].state_before[3], abs=1e-6)
    assert orbit.period == pytest.approx(touchdowns[-1].time - touchdowns[-2].time, abs=2e-3)
    moduli = sorted(abs(orbit.multipliers))
    assert moduli[-1] == pytest.approx(1.0, abs=1e-6) and moduli[-2] < 0.5
