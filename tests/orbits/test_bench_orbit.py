"""``legsim bench orbit`` (legsim/bench/orbit.py): the scipy baseline's step map and Newton
iteration, and the report's accuracy bookkeeping (no timings asserted)."""

import json
import math

import numpy as np
import pytest

from helpers.reliability import run_cli
from legsim.bench import orbit
from legsim.orbits import find_orbit
from legsim.scene import load_scene
from legsim.scene.orbit import problem_from_scene


@pytest.fixture(scope="module")
def compass():
    return problem_from_scene(load_scene("compass_gait"))


def test_scipy_newton_and_legsim_find_the_same_compass_gait(compass):
    # Two independent codes (solve_ivp DOP853 with events and finite-difference Newton; the
    # relaxed RK4 with the saltation Jacobian), each accurate to ~1e-11 here.
    ours = find_orbit(compass.problem, compass.guess, **dict(compass.solver, tol=1e-11))
    theirs = orbit.scipy_newton(compass.problem, compass.guess, 1e-12, 0.0, multipliers=True)
    idx = compass.problem.unknown_idx
    assert ours.converged and theirs.residual < 1e-12
    assert np.max(np.abs(ours.fixed_point[idx] - theirs.fixed_point[idx])) < 1e-9
    # legsim's multipliers are good to ~1e-7 (test_walkers); the baseline's forward differences
    # at a relative step 1e-6 to about that step times |P''| (measured 1.1e-5 on the complex pair).
    assert np.max(np.abs(np.sort_complex(ours.multipliers) - np.sort_complex(theirs.multipliers))) < 5e-5


def test_the_step_map_returns_the_fixed_point_to_itself_and_counts_its_work(compass):
    step_map = orbit.StepMap(compass.problem, 1e-12)
    fixed = orbit.scipy_newton(compass.problem, compass.guess, 1e-12, 0.0).fixed_point
    idx = compass.problem.unknown_idx
    assert np.max(np.abs(step_map(fixed)[idx] - fixed[idx])) < 1e-11
    assert step_map.calls == 1 and step_map.field_evals > 0


def test_the_report_picks_a_baseline_at_least_as_accurate_as_legsim():
    code, out, err = run_cli("bench", "orbit", "--repeats", "1", "--json")
    assert code == 0, err
    r = json.loads(out)
    assert r["legsim"]["error"] < 1e-9  # the scene's tol 1e-10 on RK4 at h = 2e-3
    assert r["scipy"]["error"] <= r["legsim"]["error"] and r["scipy"]["residual"] <= r["orbit_tol"]
    looser = [row for row in r["sweep"] if row["tol"] > r["scipy"]["tol"]]
    assert all(row["error"] > r["legsim"]["error"] or row["residual"] > r["orbit_tol"] for row in looser)
    assert math.isclose(r["ratio"], r["scipy"]["wall_s"] / r["legsim"]["wall_s"])
    # The bracketing tolerance: the next looser one in the sweep, less accurate than legsim.
    looser = r["scipy_looser"]
    assert looser["tol"] == min(row["tol"] for row in r["sweep"] if row["tol"] > r["scipy"]["tol"])


@pytest.mark.parametrize(
    "argv, message",
    [
        (("--repeats", "0"), "--repeats must be >= 1"),
        (("--scene", "slip_orbit"), "needs a section after a transition"),
        (("--scene", "bouncing_ball"), "no [orbit] section"),
    ],
)
def test_bad_requests_are_refused_with_a_message(argv, message):
    code, _out, err = run_cli("bench", "orbit", "--quiet", *argv)
    assert code != 0 and message in err and "Traceback" not in err
