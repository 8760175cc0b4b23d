"""A level section's return located on the run's own step (``legsim.orbits.section_points``):
the biped runner's return map without the stored points' interpolation noise, and its gait found
as an orbit to 1e-9 with a stability verdict at its scene's own search settings."""

import json

import numpy as np
import pytest

from legsim.cli import main
from legsim.crossings import returns
from legsim.orbits.returns import ReturnMap
from legsim.scene import load_scene
from legsim.scene.orbit import problem_from_scene


def _require_native():
    from legsim.robots import _native

    if _native.status() != "available":
        pytest.skip(f"the biped needs the native library: {_native.status()}")


def test_the_returns_point_on_the_runs_step_removes_the_interpolants_noise():
    """Starts 1e-11 apart (relative) return 1e-8 apart on the run's own step, while the cubic
    Hermite interpolant of the same runs' stored points puts them up to 1e-5 apart (its error,
    h^4 |x''''| / 384 in the knee rates under their servos, moves with the stored points)."""
    _require_native()
    # The scene's [orbit.integrator]: dop853 at 1e-14, dense landing, eps = 1e-11, h = 2e-3.
    settings = problem_from_scene(load_scene("biped_run"))
    problem, z, memory = settings.problem, settings.guess, settings.solver["memory"]
    rmap = ReturnMap(problem)
    rng = np.random.default_rng(0)
    on_step, interpolated = [], []
    for _ in range(6):
        start = z + 1e-11 * rng.standard_normal(z.shape) * np.maximum(1.0, np.abs(z))
        ret = rmap(start, memory=memory)
        on_step.append(ret.x_end)
        found = returns(ret.execution, problem.bound.mode, problem.bound.s, problem.section.direction,
                        problem.min_transitions, problem.min_time)  # fmt: skip
        k, _, x_hit = [hit for _, hit in zip(range(problem.returns), found, strict=False)][-1]
        assert k == ret.segment
        interpolated.append(x_hit[: problem.dim])
    assert np.ptp(np.array(on_step), axis=0).max() < 1e-8
    assert np.ptp(np.array(interpolated), axis=0).max() > 1e-7


# Slow (about 45 s, 193 returns at dop853 1e-14), like the quadrupeds' gaits in
# test_gait_scenes.py; CI's short form is the map on the run's own step above and the hoppers'
# gaits found to 1e-9 there.
@pytest.mark.slow
def test_the_biped_gait_is_found_to_1e_9_and_is_stable(capsys):
    _require_native()
    code = main(["orbit", "biped_run", "--json"])
    out, _ = capsys.readouterr()
    data = json.loads(out)
    assert code == 0 and data["status"] == "converged", data["message"]
    assert data["residual"] <= 1e-9
    # ... at a tolerance the map resolves: no warning that tol is tighter than its noise allows.
    assert data["map_accuracy"]["resolved"] <= 1e-9 and data["warnings"] == []
    # Central, forward and backward differences agree on the multipliers (no kink: the memory
    # flags the orbit holds fixed are not differentiated); the largest pair |mu| = 0.90.
    assert data["differentiable"] is True and data["kinked_coordinates"] == []
    assert data["stable"] is True and 0.5 < data["spectral_radius"] < 1.0
    assert data["period"] == pytest.approx(0.775, abs=1e-3)
    assert data["transitions"] == [
        "touchdown_left", "slip_left>", "liftoff_left", "touchdown_right", "slip_right>", "liftoff_right",
    ]  # fmt: skip
