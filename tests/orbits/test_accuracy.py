"""What the return map resolves (``legsim.orbits.accuracy``): a search reports "converged" only at
a residual within tol *and* within the map's own resolution; a map that jumps at the point is
``map_unresolved`` whatever the residual."""

import math

import numpy as np
import pytest

from helpers.orbit_systems import impact_oscillator, oscillator_closed_form
from legsim import HybridSystem, Mode, Transition
from legsim.orbits import OrbitProblem, Section, find_orbit
from legsim.orbits.accuracy import NOISE_STEP, RESOLVED_FACTOR, ROUNDING


def test_a_guess_within_a_loose_tol_but_above_the_maps_resolution_is_refined():
    # The impact oscillator's map is linear (V -> e rho V + D) and reproducible to rounding: a
    # guess 1e-5 off satisfies tol = 1e-3 at once, yet it is no orbit to the map's accuracy,
    # so Newton's method goes on to the closed-form fixed point.
    exact = oscillator_closed_form()
    problem = OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-3, eps=1e-8, t_max=5.0)
    result = find_orbit(problem, {"x": 0.0, "v": exact["v"] + 1e-5}, tol=1e-3)
    assert result.converged and result.iterations >= 1
    acc = result.map_accuracy
    assert acc is not None and acc.noise < 1e-13 and result.residual <= acc.resolved
    assert result.history[0] > acc.resolved  # the guess alone was above what the map resolves
    assert result.fixed_point[1] == pytest.approx(exact["v"], abs=1e-6)  # the rk4 map's orbit, h = 1e-3
    # the refined map (h/2, eps/2) moves the equations by the integrator's error: far below tol
    assert acc.refinement < 1e-9 and result.warnings == []


def test_a_tol_tighter_than_the_map_resolves_is_a_warning():
    problem = OrbitProblem(impact_oscillator(), Section.after("impact"), h=1e-3, eps=1e-8, t_max=5.0)
    result = find_orbit(problem, {"x": 0.0, "v": 1.8}, tol=1e-16)
    if result.converged:  # the residual may land at 0 by chance: then the warning says so
        assert any(w.startswith("tol 1e-16 is tighter than the return map resolves") for w in result.warnings)
    else:
        assert result.status == "stalled" and "tol 1e-16 is tighter than the return map resolves" in result.message
    floor = ROUNDING * (1.0 + abs(result.fixed_point[1]))
    assert result.map_accuracy is not None and result.map_accuracy.resolved >= floor


def jump_lap(jump, offset=0.0):
    """y decays over a lap of time 1 (y' = -y / 2) and resets to 0.3 y + ``offset``, plus ``jump``
    when y < 0: a return map with its fixed point y* = 0 at a jump of size ``jump`` (the + side's)
    for offset 0."""

    def reset(x):
        return np.array([0.3 * x[0] + offset + (jump if x[0] < 0 else 0.0), 0.0])

    return HybridSystem(
        {"lap": Mode(2, lambda t, x, u: np.array([-0.5 * x[0], 1.0]), names=("y", "theta"))},
        [Transition("lap", "lap", guard=lambda x: 1.0 - x[1], reset=reset, name="restart")],
        name="jump lap",
    )


def test_a_map_that_jumps_at_the_orbit_is_unresolved_whatever_the_residual():
    problem = OrbitProblem(
        jump_lap(1e-2), Section.level("lap", "theta", 0.5, "increasing"), h=1e-2, eps=1e-6, t_max=3.0
    )
    result = find_orbit(problem, [0.0, 0.5], tol=1e-3, jacobian="fd")
    # y* = 0 returns to 0 exactly (residual 0), but a probe of 1e-11 below it returns 1e-2
    # higher: the second difference is half the jump (times the flow's decay, exp(-1/4), from
    # the reset to the section).
    assert result.status == "map_unresolved" and result.residual == 0.0 and result.iterations == 0
    assert result.map_accuracy.noise == pytest.approx(0.5e-2 * math.exp(-0.25), rel=1e-3)
    assert result.map_accuracy.noisiest == "y" and "does not resolve tol" in result.message
    # without the jump the same point is an orbit
    smooth = OrbitProblem(jump_lap(0.0), problem.section, h=1e-2, eps=1e-6, t_max=3.0)
    assert find_orbit(smooth, [0.0, 0.5], tol=1e-3, jacobian="fd").converged


def test_a_search_stuck_at_a_jump_above_tol_is_unresolved_not_diverged():
    # offset -1e-4, jump 3e-4: the orbit equation is k (offset + jump) - (1 - 0.3 k^2) y > 0 for
    # y < 0 and k offset - (1 - 0.3 k^2) y < 0 for y >= 0 (k = exp(-1/4), the flow's decay from
    # the section to the reset and back): no fixed point, and Newton's method ends at y = 0 with
    # the residual k 1e-4 that no step lowers. That is the map's jump, not a search gone astray.
    k = math.exp(-0.25)
    problem = OrbitProblem(
        jump_lap(3e-4, offset=-1e-4), Section.level("lap", "theta", 0.5, "increasing"), h=1e-2, eps=1e-6, t_max=3.0
    )
    result = find_orbit(problem, [1.0, 0.5], tol=1e-9, jacobian="fd")
    assert result.status == "map_unresolved" and result.residual > 1e-9
    assert result.residual == pytest.approx(k * 1e-4, rel=1e-3)
    assert result.map_accuracy.noise == pytest.approx(0.5 * 3e-4 * k, rel=1e-3)
    assert "no Newton step lowers the residual" in result.message and result.multipliers is None
    # the same lap without the jump has its orbit where the equation's one piece vanishes
    smooth = find_orbit(
        OrbitProblem(jump_lap(0.0, offset=-1e-4), problem.section, h=1e-2, eps=1e-6, t_max=3.0), [1.0, 0.5],
        tol=1e-9, jacobian="fd",
    )  # fmt: skip
    assert smooth.converged and smooth.fixed_point[0] == pytest.approx(-1e-4 * k / (1 - 0.3 * k * k), rel=1e-6)


def test_the_noise_probe_is_small_enough_for_kinks():
    # A kink's second difference is NOISE_STEP times the slope jump: below tol 1e-9 for slope
    # jumps up to 10 once multiplied by the resolved factor.
    assert RESOLVED_FACTOR * NOISE_STEP * 10 <= 1e-9


@pytest.mark.slow
def test_the_quadruped_pronk_is_found_where_its_map_is_not_differentiable():
    # At the symmetric pronk the legs' slip and liftoff order switches with the sign of any
    # asymmetry (tests/orbits/test_kinks.py): the stored guess, an apex of the scene's settled
    # run, is 1.7e-7 from periodic. The first Newton step, from differences that mix the map's
    # pieces, raises the residual and no halving of it lowers it; the watchdog's full steps go
    # on and converge (linearly, as at a kink) within what the map resolves. The Jacobian there
    # is reported kinked, never as the orbit's derivative; the verdict comes from the pieces
    # (``docs/orbits.md``).
    from legsim.scene import load_scene
    from legsim.scene.orbit import problem_from_scene

    settings = problem_from_scene(load_scene("quadruped_pronk"))
    result = find_orbit(settings.problem, settings.guess, **settings.solver)
    assert result.converged and result.residual <= 1e-9
    assert result.residual <= result.map_accuracy.resolved
    assert max(result.history) > result.history[0]
    assert "full steps past a rise of the residual" in result.message
    assert result.differentiable is False and "pitch" in result.kinked_coordinates
    # the gait in place: no forward speed or pitch beyond what the residual allows
    state = dict(zip(result.state_names, result.fixed_point, strict=True))
    assert abs(state["pitch"]) < 1e-7 and abs(state["xd"]) < 1e-5
    # Three pairs of simultaneous events (touchdowns, slips, liftoffs): eight regions, each its
    # piece (legsim.orbits.sampled_pieces), all contracting in one quadratic norm.
    verdict = result.piecewise
    assert verdict.kind == "stable" and result.stable is True, verdict.reason
    assert len(verdict.details["samples"]) == 8 and verdict.details["factor"] < 1.0


def test_a_map_whose_probes_all_fail_says_so_without_a_made_up_noise():
    from legsim.orbits.accuracy import estimate_accuracy
    from legsim.orbits.errors import OrbitError

    def no_return(z):
        raise OrbitError("no return next to the point", status="no_return")

    accuracy = estimate_accuracy(np.zeros(2), np.zeros(2), no_return, None, "h = 1e-3 s")
    text = accuracy.describe()
    assert "nan" not in text and "measured no noise" in text and "the noise is not known" in text
    assert math.isinf(accuracy.resolved) and accuracy.to_json()["noise"] is None
