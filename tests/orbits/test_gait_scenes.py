"""``legsim orbit`` on the bundled controlled gait scenes (docs/orbits.md, "Every gait as an
orbit"): the hoppers' gaits are found to residual <= 1e-9 with a stability verdict; the
articulated runners' return maps jump where their touchdowns graze, which the search reports as
``map_unresolved`` with the jump measured, never as an orbit."""

import pytest

from legsim.orbits import find_orbit
from legsim.scene import load_scene
from legsim.scene.orbit import problem_from_scene


def search(name, overrides=()):
    settings = problem_from_scene(load_scene(name, list(overrides)))
    return find_orbit(settings.problem, settings.guess, **settings.solver)


@pytest.mark.parametrize(
    ("name", "radius"),
    # the leading multipliers: the SLIP's apex-speed mode; the pronk's pitch pair (its pieces,
    # one per touchdown order, give the verdict: tests/orbits/test_piecewise.py)
    [("slip_raibert", 0.258964), ("pronk_raibert", 0.264367)],
)
def test_the_hoppers_gaits_are_found_to_1e_9_with_a_verdict(name, radius):
    result = search(name)
    assert result.converged and result.residual <= 1e-9, result.message
    assert result.stable is True
    assert result.spectral_radius == pytest.approx(radius, abs=1e-4)
    # the energy's multiplier 1 is left out of the verdict
    assert min(abs(abs(mu) - 1.0) for mu in result.multipliers) < 1e-5


@pytest.mark.slow
def test_a_runner_whose_map_jumps_at_a_grazing_touchdown_is_unresolved():
    # The hind foot's touchdown starts with a graze or not as rounding decides (its contact
    # force right after the impact is ~0: the leg lands at its rest length), and the return map
    # jumps between the two by 1e-4 .. 1e-3 at h = 1e-3 and eps = 5e-5, where the jump stops
    # Newton's method at the stored guess; the report says so and gives no multipliers.
    result = search("quadruped_run", ["integrator.h=1e-3", "integrator.eps=5e-5"])
    assert result.status == "map_unresolved" and result.residual > 1e-9
    acc = result.map_accuracy
    assert acc is not None and result.residual <= acc.resolved and acc.noise > 1e-5
    assert "no Newton step lowers the residual" in result.message
    assert result.multipliers is None and result.stable is None


@pytest.mark.slow
def test_a_biped_whose_map_jumps_ends_diverged_above_what_its_map_resolves():
    # The biped's map is as noisy there (its left touchdown grazes as rounding decides), but
    # the search leaves the guess and stalls at a residual (5e-3, measured 2026-11-29) above
    # what the map resolves (3.5e-3): no orbit near the last iterate, said as `diverged` with the
    # map's accuracy, never as an orbit.
    result = search("biped_run", ['orbit.integrator={method="rk4", h=1e-3, eps=5e-5, landing="halve"}'])
    assert result.status == "diverged" and not result.converged
    acc = result.map_accuracy
    assert acc is not None and acc.noise > 1e-5 and result.residual > acc.resolved
    assert "the map's noise does not explain it" in result.message
    assert result.multipliers is None and result.stable is None


@pytest.mark.slow
def test_a_runner_whose_map_jumps_is_not_reported_as_an_orbit_at_its_scenes_settings():
    # At the scene's own finer settings: no orbit either. quadruped_run's Newton iterate reaches
    # a point where the finite-difference Jacobian degenerates along the knees' rates (the jumps
    # of the map between columns): `singular_jacobian`, which names those coordinates. (The
    # biped's gait is found at its scene's search settings: tests/orbits/test_section_points.py.)
    result = search("quadruped_run")
    assert not result.converged and result.residual > 1e-9
    assert result.status in ("map_unresolved", "diverged", "singular_jacobian"), result.message
    assert result.multipliers is None and result.stable is None
