"""The differentiability check of finite-difference return-map Jacobians (``legsim.orbits.kinks``).

A return map with a kink at its fixed point has no Jacobian there: central differences average
the two one-sided slopes, and their multipliers belong to neither side. The test bed is a
*kinked lap*: y decays (y' = -lam y) while a clock theta runs to T, then a reset scales y by a
gain that depends on its sign (a for y > 0, b for y < 0, as when the order of two transitions
switches at y = 0) and restarts the clock. Its return map on theta = T/2 is, in closed form,
y -> a rho y (y > 0) and b rho y (y < 0) with rho = exp(-lam T) (to the integrator's error): a
fixed point y* = 0 with one-sided multipliers a rho and b rho, and the central difference's
(a + b) rho / 2.
"""

import math

import numpy as np
import pytest

from helpers.orbit_systems import hopf_closed_form, hopf_reset
from legsim import HybridSystem, Mode, Transition
from legsim.commands.orbit import format_orbit, format_row
from legsim.errors import ModelBreakdown
from legsim.orbits import OrbitProblem, Section, continue_family, find_orbit
from legsim.orbits.kinks import KINK_RATIO, ColumnStencil, kinked_columns

LAM, T = 0.5, 1.0
RHO = math.exp(-LAM * T)
#: A stable side (multiplier 0.18) and an unstable one (1.6) whose average (0.89) is stable: the
#: central difference would call the orbit stable although any start with y < 0 moves away.
A_SIDE, B_SIDE = 0.3, 1.6 / RHO


def kinked_lap(params):
    """The kinked lap (module docstring) with gains ``a`` (y > 0) and ``b`` (y < 0)."""
    a, b = params["a"], params["b"]

    def reset(x):
        return np.array([(a if x[0] > 0 else b) * x[0], 0.0])

    return HybridSystem(
        {"lap": Mode(2, lambda t, x, u: np.array([-LAM * x[0], 1.0]), names=("y", "theta"))},
        [Transition("lap", "lap", guard=lambda x: T - x[1], reset=reset, name="restart")],
        name="kinked lap",
    )


def lap_problem(a, b):
    return OrbitProblem(
        kinked_lap,
        Section.level("lap", "theta", T / 2, "increasing"),
        h=1e-2,
        eps=1e-6,
        t_max=3.0,
        parameters={"a": a, "b": b},
    )


@pytest.fixture(scope="module")
def kinked():
    return find_orbit(lap_problem(A_SIDE, B_SIDE), [0.4, T / 2], jacobian="fd")


# -- the check on one column, against closed forms ---------------------------------------------
def stencil(fn, x, d):
    return ColumnStencil(fn(x), fn(x + d), fn(x - d), fn(x + d / 2), d)


@pytest.mark.parametrize("offset", [-0.9, -0.5, 0.0, 0.05, 0.4, 0.6, 0.9])
def test_a_kink_inside_the_stencil_is_flagged(offset):
    # slopes 2 left and 0.5 right of a kink at x + offset * d, away from the blind band
    # d/9 .. d/3 (kinks.py): the forward and backward slopes cannot both be linear in h.
    d, x = 1e-6, 0.3
    kink = x + offset * d

    def fn(t):
        return np.array([2.0 * min(t - kink, 0.0) + 0.5 * max(t - kink, 0.0)])

    assert kinked_columns({0: stencil(fn, x, d)}, np.array([[1.25]])) == (0,)


def test_at_the_kink_the_one_sided_differences_are_the_two_slopes():
    s = stencil(lambda t: np.array([2.0 * min(t, 0.0) + 0.5 * max(t, 0.0)]), 0.0, 1e-6)
    assert s.forward[0] == pytest.approx(0.5, abs=1e-9)
    assert s.backward[0] == pytest.approx(2.0, abs=1e-9)


@pytest.mark.parametrize("step", [1e-6, 1e-4, 1e-2])
@pytest.mark.parametrize("fn", [np.exp, np.sin, lambda t: t**3 - 5 * t, lambda t: np.full_like(t, 3.0)])
def test_smooth_functions_are_not_flagged_at_any_step(fn, step):
    # A smooth map's defect is d^2 P'''/2 (here <= 1e-4 * 6 / 2 = 3e-4 at the largest step), far
    # below the floor 1e-3 * |P'| when P' is O(1); for the constant map it is rounding.
    vector = lambda t: np.array([fn(np.float64(t))])  # noqa: E731
    s = stencil(vector, 0.7, step)
    slope = (vector(0.7 + 1e-7) - vector(0.7 - 1e-7)) / 2e-7
    assert kinked_columns({0: s}, np.array([[max(abs(slope[0]), 1.0)]])) == ()


@pytest.mark.parametrize("offset", [0.1, 0.115, 0.2, 0.33, 0.34])
def test_the_blind_band_is_where_the_docstring_says(offset):
    # A kink at x + s d with 0 < s < 1/2: defect |1 - 5 s| |a - b|, gap (1 - s) |a - b|, predicted
    # gap 4 s |a - b|, so with KINK_RATIO = 1/2 it is missed exactly for 1/9 < s < 1/3 (at s = 0.2
    # the four points fit a piecewise-linear map).
    d, x = 1e-3, 0.0
    kink = offset * d
    fn = lambda t: np.array([2.0 * min(t - kink, 0.0) + 0.5 * max(t - kink, 0.0)])  # noqa: E731
    missed = kinked_columns({0: stencil(fn, x, d)}, np.array([[2.0]])) == ()
    assert KINK_RATIO == 0.5
    assert missed == (1 / 9 < offset < 1 / 3)


# -- the orbit search on the kinked lap ----------------------------------------------------------
def test_the_kink_at_the_fixed_point_is_found_and_named(kinked):
    assert kinked.converged and abs(kinked.fixed_point[0]) < 1e-9
    assert kinked.differentiable is False
    assert kinked.kinked_coordinates == ("y",)
    assert kinked.stable is None
    assert len(kinked.warnings) == 1 and "column(s) of y" in kinked.warnings[0]


def test_each_sides_multiplier_is_its_closed_form(kinked):
    # One multiplier per side (theta is the flow's direction). The return map is linear on each
    # side, so a one-sided difference is exact up to rounding over the step (1e-10), the
    # integrator's error in rho (RK4, h = 1e-2: 1e-11 relative) and the share of the step that
    # lies beyond the kink: Newton stops at |y*| ~ 5e-12, a fraction |y*| / d of the step
    # d = 1e-6 on the other side, which moves that side's slope by |y*| / d * |a - b| rho.
    d = 1e-6
    beyond = abs(kinked.fixed_point[0]) / d * abs(A_SIDE - B_SIDE) * RHO
    assert beyond < 1e-4
    assert abs(kinked.multipliers_forward[0] - A_SIDE * RHO) < 1e-8 + beyond
    assert abs(kinked.multipliers_backward[0] - B_SIDE * RHO) < 1e-8 + beyond
    # The central difference averages them: 0.89, which alone would read "stable".
    assert abs(kinked.multipliers[0] - (A_SIDE + B_SIDE) * RHO / 2) < 1e-8 + beyond
    assert kinked.spectral_radius < 1.0 < abs(kinked.multipliers_backward[0])


def test_json_and_text_say_unresolved(kinked):
    payload = kinked.to_json()
    assert payload["stable"] is None and payload["differentiable"] is False
    assert payload["kinked_coordinates"] == ["y"]
    assert payload["multipliers_forward"][0] == [kinked.multipliers_forward[0].real, 0.0]
    assert payload["multipliers_backward"][0] == [kinked.multipliers_backward[0].real, 0.0]
    text = format_orbit(payload, "kinked lap")
    assert "\nunresolved: by the piecewise-linear derivative (central differences' spectral radius 0.89" in text
    # The lap's kink is a reset that depends on y's sign, not an order of events: every return
    # takes the one transition, so there are no event orders to tell the pieces apart.
    assert payload["piecewise"]["verdict"] == "unresolved"
    assert "1 transition order(s) among the stencil's returns (restart)" in payload["piecewise"]["reason"]
    lines = {line.split(":")[0].strip(): line.split(":")[1] for line in text.splitlines() if ":" in line}
    assert float(lines["backward-difference multipliers"].split()[0]) == pytest.approx(1.6, abs=1e-4)
    assert float(lines["forward-difference multipliers"].split()[0]) == pytest.approx(A_SIDE * RHO, abs=1e-4)
    assert "warning: the return map is not differentiable at the orbit" in text
    assert "stable:" not in text


@pytest.mark.parametrize("share", [0.1, 0.2, 0.3])
def test_newton_steps_past_a_rise_of_the_residual_reach_the_orbit_at_a_kink(share, monkeypatch):
    """A start within the difference stencil of the kink (y = share * d, d the step): the
    central differences mix the sides' slopes a rho and b rho into one above 1 while the side
    the start is on contracts, so the Newton step moves away and no halving of it lowers the
    residual. The watchdog's full steps (``legsim.orbits.newton``) leave the stencil and reach
    y* = 0 by the side's exact slope; without them the search stops there, ``diverged``."""
    from legsim.orbits import newton
    from legsim.orbits.jacobians import default_fd_step

    problem = lap_problem(A_SIDE, B_SIDE)
    start = [share * default_fd_step(problem), T / 2]
    found = find_orbit(problem, start, jacobian="fd")
    assert found.converged and abs(found.fixed_point[0]) < 1e-12
    assert max(found.history) > found.history[0]  # the residual rose before it fell
    assert "full steps past a rise of the residual" in found.message
    monkeypatch.setattr(newton, "WATCHDOG_STEPS", 0)
    stopped = find_orbit(problem, start, jacobian="fd")
    assert stopped.status == "diverged" and "no Newton step" in stopped.message


def test_equal_gains_are_smooth_and_not_flagged():
    # No false positive: the same lap with a = b is linear, multiplier a rho.
    result = find_orbit(lap_problem(0.8, 0.8), [0.4, T / 2], jacobian="fd")
    assert result.differentiable is True and result.kinked_coordinates == () and result.warnings == []
    assert result.multipliers.real == pytest.approx([0.8 * RHO], rel=1e-8)
    assert result.stable is True
    payload = result.to_json()
    assert payload["multipliers_forward"] is None and payload["multipliers_backward"] is None


def test_a_smooth_nonlinear_map_keeps_its_multiplier():
    # The Hopf oscillator with a reset: nonlinear field, guard and reset, closed-form multiplier.
    prob = OrbitProblem(hopf_reset(), Section.after("jump"), h=2e-3, eps=1e-4, t_max=2.0)
    result = find_orbit(prob, [-0.35, -0.55], jacobian="fd", tol=1e-12)
    assert result.differentiable is True and result.stable is True
    # the FD multiplier against the closed form: the integrator's O(h^4) and the step's O(d^2)
    assert abs(result.multipliers[0] - hopf_closed_form()["multiplier"]) < 1e-6


def test_the_saltation_jacobian_is_not_checked():
    prob = OrbitProblem(hopf_reset(), Section.after("jump"), h=2e-3, eps=1e-4, t_max=2.0)
    result = find_orbit(prob, [-0.35, -0.55])
    assert result.differentiable is None and result.to_json()["differentiable"] is None


def test_continuation_reports_no_stability_change_between_unresolved_orbits():
    # Over b the central spectral radius (0.3 + b) rho / 2 crosses 1 at b = 2 / rho - 0.3, but no
    # orbit of the family has a verdict: no change is reported, and the table says unresolved.
    family = continue_family(lap_problem(A_SIDE, 1.0), "b", 1.0, 4.0, 3, [0.4, T / 2], jacobian="fd")
    radii = [p.result.spectral_radius for p in family.points]
    assert min(radii) < 1.0 < max(radii)
    assert all(p.result.stable is None for p in family.points)
    assert family.stability_changes == []
    layout = (["b", "stable"], [12, 12])
    assert format_row("b", 1.0, family.points[0].result.to_json(), layout).split() == ["1", "unresolved"]


@pytest.mark.slow
def test_the_symmetric_pronks_event_order_switches_with_the_sign_of_an_asymmetry():
    """Why `legsim orbit quadruped_pronk` needs the watchdog: at its symmetric gait (front and hind
    legs mirrored, pitch 0) a pitch of +1e-9 or -1e-9 rad switches which foot slips first and
    which leg lifts off first, while a symmetric perturbation (the height) keeps the order. The
    return map stays continuous (a 1e-9 perturbation moves the return by less than 1e-7) but has
    one linear piece per order, and difference quotients across the switch give a Newton step
    that raises the residual before the next ones lower it (tests/orbits/test_accuracy.py).
    Slow: about 10 s."""
    from legsim.orbits.returns import ReturnMap
    from legsim.scene import load_scene
    from legsim.scene.orbit import problem_from_scene

    settings = problem_from_scene(load_scene("quadruped_pronk"))
    rmap, names = ReturnMap(settings.problem), list(settings.problem.names)
    base = rmap(settings.guess)

    def perturbed(name, delta):
        x = settings.guess.copy()
        x[names.index(name)] += delta
        ret = rmap(x)
        return [tr.name for tr in ret.transitions], float(np.max(np.abs(ret.x_end - base.x_end)))

    (up, moved_up), (down, moved_down) = perturbed("pitch", 1e-9), perturbed("pitch", -1e-9)
    assert up != down and {up[-1], down[-1]} == {"liftoff_front@flight", "liftoff_hind@flight"}
    assert max(moved_up, moved_down) < 1e-7
    assert perturbed("z", 1e-9)[0] == perturbed("z", -1e-9)[0]


def test_a_column_whose_stencil_cannot_be_simulated_is_not_called_differentiable():
    """The lap's reset past y < 0 is outside its model's range (a ModelBreakdown): the y column's
    backward difference cannot be taken, so the column is one-sided and unchecked, the verdict
    is not "differentiable" but unknown (None), and a warning names the column."""

    def lap_ending_below_zero(params):
        system = kinked_lap(params)

        def reset(x):
            if x[0] < 0:
                raise ModelBreakdown("y below 0: outside this lap's range")
            return np.array([params["a"] * x[0], 0.0])

        return HybridSystem(
            system.modes,
            [Transition("lap", "lap", guard=lambda x: T - x[1], reset=reset, name="restart")],
            name="lap ending below 0",
        )

    problem = lap_problem(A_SIDE, B_SIDE)
    problem = OrbitProblem(
        lap_ending_below_zero,
        problem.section,
        h=problem.h,
        eps=problem.eps,
        t_max=problem.t_max,
        parameters={"a": A_SIDE, "b": B_SIDE},
    )
    result = find_orbit(problem, [0.4, T / 2], jacobian="fd")
    assert result.converged and abs(result.fixed_point[0]) < 1e-9
    assert result.differentiable is None and result.kinked_coordinates == ()
    assert any("could not compare" in w and "of y" in w for w in result.warnings)
    # The one-sided (forward) difference is the stable side's slope a rho: the multiplier reported.
    assert result.multipliers[0].real == pytest.approx(A_SIDE * RHO, abs=1e-6)
