"""SLIP: closed-form flight, angular momentum about the foothold in stance, energy at the
method's order, effect switching."""

import math

import numpy as np
import pytest
from legsim.robots import slip

from legsim import simulate
from legsim.graph import reachable_modes


def test_touchdown_time_and_foothold_are_the_ballistic_closed_form():
    model = slip.make()
    z0, xd0, psi, g, rest_length = 1.1, 3.4, math.pi / 5, 9.81, 1.0
    ex = simulate(model.system, slip.state(), "flight", 0.4, 1e-3, 1e-3)
    td = ex.transitions[0]
    t_td = math.sqrt(2 * (z0 - rest_length * math.cos(psi)) / g)
    # free fall is a quadratic: RK4 and the Hermite crossing are exact to rounding
    assert td.name == "touchdown_leg" and td.time == pytest.approx(t_td, abs=1e-12)
    assert td.state_after[-1] == pytest.approx(xd0 * t_td + rest_length * math.sin(psi), abs=1e-12)
    assert model.system.state_names("stance") == ("x", "z", "xd", "zd", "leg_foot_x")


def test_stance_without_gravity_conserves_angular_momentum_about_the_foothold():
    # With g = 0 the leg force is central about the pinned foot.
    model = slip.make(effects={"gravity": False})
    ex = simulate(model.system, slip.state({"zd": -2.0}), "flight", 1.0, 1e-3, 1e-3)
    assert [tr.name for tr in ex.transitions][:2] == ["touchdown_leg", "liftoff_leg"]
    stance = next(seg for seg in ex.segments if seg.mode == "stance")
    x, z, xd, zd, foot = stance.x.T
    L = (x - foot) * zd - z * xd
    assert np.ptp(L) < 1e-9 and abs(L[0]) > 1.0
    # and without gravity the flights are straight lines at constant velocity
    lo = ex.transitions[1]
    speed_td = np.hypot(*ex.transitions[0].state_before[2:4])
    assert np.hypot(*lo.state_after[2:4]) == pytest.approx(speed_td, rel=1e-8)


@pytest.mark.parametrize("method,order,hs", [("rk2", 2, (4e-3, 2e-3, 1e-3)), ("rk4", 4, (1.6e-2, 8e-3, 4e-3))])
def test_energy_drift_shrinks_at_the_method_order(method, order, hs):
    model = slip.make()
    x0 = slip.state()
    E0 = model.system.energy("flight", x0)
    errs = []
    for h in hs:
        ex = simulate(model.system, x0, "flight", 2.0, h, 1e-2, method=method)
        assert [tr.name for tr in ex.transitions] == ["touchdown_leg", "liftoff_leg"] * 2
        errs.append(max(abs(model.system.energy(s.mode, x) - E0) for s in ex.segments for x in s.x))
        for tr in ex.transitions:  # continuous through every transition (bound O(eps^2))
            assert (
                abs(model.system.energy(tr.target, tr.state_after) - model.system.energy(tr.source, tr.state_before))
                < 1e-2**2 * 1e-6
            )
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert slope > order - 0.25, (errs, slope)


def test_damping_term_only_when_asked():
    plain = slip.make()
    simulate(plain.system, slip.state(), "flight", 1.0, 1e-3, 1e-2)
    assert plain.counters()["damping_evals"] == 0 and plain.counters()["spring_forces"] > 0
    damped = slip.make(effects={"damping": {"b": 1.0}})
    ex = simulate(damped.system, slip.state(), "flight", 1.0, 1e-3, 1e-2)
    c = damped.counters()
    assert c["damping_evals"] == c["spring_forces"] > 0
    E = [damped.system.energy(s.mode, x) for s in ex.segments for x in s.x]
    assert E[-1] < E[0] - 0.1
    assert sorted(reachable_modes(plain.system, "flight")) == ["flight", "stance"]


def test_a_runner_whose_hip_reaches_the_ground_ends_with_model_breakdown():
    # A 5 N/m leg cannot hold 1 kg: the mass sinks through its stance to the ground, where the
    # model (no body-ground contact) stops being physical. The run ends with model_breakdown,
    # keeping the execution up to the last step with the hip above the ground.
    model = slip.make({"k": 5.0})
    ex = simulate(model.system, slip.state(), "flight", 3.0, 1e-3, 1e-3)
    assert ex.status == "model_breakdown" and "range" in ex.message
    assert ex.mode_sequence == ["flight", "stance"]
    assert 0.0 <= ex.final_state[1] < 0.01 and ex.final_state[3] < 0
