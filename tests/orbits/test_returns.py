"""The return map: where a trajectory comes back to the section, after how many returns, and
when it does not."""

import numpy as np
import pytest

from helpers.orbit_systems import hopf_reset, impact_oscillator, oscillator_closed_form
from legsim.orbits import OrbitError, OrbitProblem, Section, find_orbit, return_map


def test_found_orbit_returns_to_itself_under_a_finer_simulation():
    # The residual is the simulation's own; a 4x finer, independent simulation of the found
    # point must return within its accuracy, O(h^4) ~ 1e-8 at h = 1e-2.
    prob = OrbitProblem(hopf_reset(), Section.after("jump"), h=1e-2, eps=1e-4, t_max=2.0)
    res = find_orbit(prob, [-0.3, -0.6], tol=1e-11)
    assert res.converged and res.residual <= 1e-11
    fine = OrbitProblem(hopf_reset(), Section.after("jump"), h=2.5e-3, eps=1e-5, t_max=2.0)
    back = return_map(fine, res.fixed_point)
    assert np.max(np.abs(back.x_end - res.fixed_point)) < 1e-7


def test_period_two_return_map_squares_the_multiplier():
    # A period-one orbit is a fixed point of P^2 too, with the multiplier squared and twice the
    # period (a period-two gait would be found the same way).
    ref = oscillator_closed_form()
    prob = OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-2, eps=1e-4, t_max=10.0, returns=2)
    res = find_orbit(prob, {"x": 0.0, "v": 1.0})
    assert res.converged, res.message
    assert abs(res.fixed_point[1] - ref["v"]) < 5e-8
    assert abs(res.multipliers[0] - ref["multiplier"] ** 2) < 1e-7
    assert abs(res.period - 2 * ref["period"]) < 1e-7
    assert res.transitions == ["impact", "impact"]


def test_no_return_within_the_time_limit():
    prob = OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-2, eps=1e-4, t_max=1.0)
    res = find_orbit(prob, {"x": 0.0, "v": 1.0})
    assert res.status == "no_return" and not res.converged
    assert "no return to the section after impact within t_max = 1 s" in res.message
    with pytest.raises(OrbitError, match="no_return"):
        res.raise_for_status()


def test_a_reset_jumping_across_the_section_is_not_a_crossing():
    # v increases through 0 only at the wall, where the reset jumps from v < 0 to v > 0: with
    # direction +1 the section is never crossed by the flow.
    prob = OrbitProblem(impact_oscillator(), Section.level("free", "v", 0.0, +1), h=1e-2, eps=1e-4, t_max=4.0)
    res = find_orbit(prob, {"x": 0.5, "v": 0.0})
    assert res.status == "no_return", res.message
    # Either direction: the decreasing crossing at the largest displacement counts.
    prob = OrbitProblem(impact_oscillator(), Section.level("free", "v", 0.0, 0), h=1e-2, eps=1e-4, t_max=4.0)
    res = find_orbit(prob, {"x": 0.5, "v": 0.0})
    assert res.converged and abs(res.fixed_point[0] - oscillator_closed_form()["x_max"]) < 5e-8


@pytest.mark.parametrize("section", [Section.after("impact"), Section.level("free", "v", 0.0, -1)])
def test_a_return_ends_its_run_soon_after_the_return_and_is_the_same(monkeypatch, section):
    # The map's run ends at the loop's first hand-back after the return instead of at its
    # horizon, and finds the very return the whole horizon's run finds.
    from legsim.orbits.returns import ReturnMap
    from legsim.relaxed.driver import STOP_CHECK_STEPS

    h = 1e-3
    prob = OrbitProblem(impact_oscillator(), section, h=h, eps=1e-4, t_max=20.0)
    x0 = [0.0, 1.0] if section.kind == "transition" else [0.5, 0.0]
    short = ReturnMap(prob)(np.array(x0))
    monkeypatch.setattr(ReturnMap, "_returned", lambda self, so_far: False)
    whole = ReturnMap(prob)(np.array(x0))
    assert short.t_return == whole.t_return and np.array_equal(short.x_end, whole.x_end)
    assert whole.execution.t_end == pytest.approx(20.0 / 8)
    assert short.t_return <= short.execution.t_end <= short.t_return + (STOP_CHECK_STEPS + 2) * h
