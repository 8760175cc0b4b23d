"""``legsim orbit`` on the bundled controlled gait scenes (docs/orbits.md, "Every gait as an
orbit"): the hoppers' gaits and the quadruped's are found to residual <= 1e-9 with a stability
verdict, the quadruped's at their scenes' finer ``[orbit.integrator]`` settings; at the runs' own
fixed steps the articulated runners' return maps jump where their touchdowns graze, which the
search reports with the jump measured, never as an orbit."""

import pytest

from legsim.orbits import find_orbit
from legsim.scene import load_scene
from legsim.scene.orbit import problem_from_scene


def search(name, overrides=()):
    settings = problem_from_scene(load_scene(name, list(overrides)))
    return find_orbit(settings.problem, settings.guess, **settings.solver)


@pytest.mark.parametrize(
    ("name", "radius"),
    # the leading multipliers: the SLIP's apex-speed mode; the pronk's pitch (at the run's own
    # coarser settings its pieces, one per touchdown order, give the verdict:
    # tests/robots/test_pronk_hopper.py)
    [("slip_raibert", 0.258965), ("pronk_raibert", 0.262713)],
)
def test_the_hoppers_gaits_are_found_to_1e_9_with_a_verdict(name, radius):
    result = search(name)
    assert result.converged and result.residual <= 1e-9, result.message
    # ... on a map resolved there, at the scenes' [orbit.integrator]: no warning
    assert result.map_accuracy.resolved <= 1e-9 and result.warnings == []
    assert result.stable is True
    assert result.spectral_radius == pytest.approx(radius, abs=1e-4)
    # the energy's multiplier 1 is left out of the verdict
    assert min(abs(abs(mu) - 1.0) for mu in result.multipliers) < 1e-5


@pytest.mark.slow
def test_a_runner_whose_map_jumps_at_a_grazing_touchdown_is_unresolved():
    # At the run's own fixed steps (rk4, h = 1e-3, eps = 5e-5) the hind foot's touchdown starts
    # with a graze or not as rounding decides (its contact force right after the impact is ~0:
    # the leg lands at its rest length), and the return map jumps between the two, which stops
    # Newton's method; the report says so and gives no multipliers.
    result = search("quadruped_run", ['orbit.integrator={method="rk4", h=1e-3, eps=5e-5, landing="halve"}'])
    assert result.status in ("map_unresolved", "diverged") and result.residual > 1e-9, result.message
    acc = result.map_accuracy
    assert acc is not None and acc.noise > 1e-5
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


#: The quadruped's gaits at their scenes' ``[orbit.integrator]`` settings: the speed the
#: scene commands (m/s; the bound in place 0), the returns' spectral radius and verdict.
QUADRUPED_GAITS = [
    ("quadruped_run", 0.6, 0.8531, True),
    ("quadruped_pronk_forward", 1.0, 1.2679, False),
    ("quadruped_bound", 0.0, 0.8805, True),
    ("quadruped_bound_forward", 1.0, 0.9992, True),
    ("quadruped_gallop", 1.0, 1.1133, False),
    ("quadruped_bound_one_flight", 1.0, 0.8915, True),
]


@pytest.mark.slow
@pytest.mark.parametrize(("name", "speed", "radius", "stable"), QUADRUPED_GAITS)
def test_the_quadrupeds_gaits_are_found_to_1e_9_on_a_map_resolved_there(name, speed, radius, stable):
    """Each gait, its controller's memory included, found to residual <= 1e-9 where the return
    map resolves 1e-9 (no warning: its noise and its change at finer settings are below tol),
    with its period, speed and verdict. The multipliers are the whole map's: a value held to
    pick one gait of a family (a thrust, a bias) keeps its column, and its multiplier 1 is the
    trivial one the scene declares."""
    result = search(name)
    assert result.converged and result.residual <= 1e-9, result.message
    assert result.map_accuracy.resolved <= 1e-9 and result.warnings == []
    assert result.step_length / result.period == pytest.approx(speed, abs=0.05)
    assert result.spectral_radius == pytest.approx(radius, abs=2e-3) and result.stable is stable
    trivial = load_scene(name).data["orbit"].get("trivial_multipliers", 0)
    assert sum(abs(mu - 1.0) < 1e-6 for mu in result.multipliers) == trivial


@pytest.mark.slow
def test_the_forward_pronks_two_hop_motion_is_no_orbit_as_its_legs_biases_drift_apart():
    """The forward pronk's run settles on a two-hop motion, not on its (unstable) one-hop orbit.
    That motion has no periodic orbit: each leg's integral term adds its own stride speed error,
    and over a two-hop cycle the legs' errors differ, so their placement biases drift apart
    without end (measured -5.8e-5, -7.6e-5, -9.8e-5 m at 20, 30, 40 s: about -2e-6 m/s),
    where a periodic motion would keep their difference. Read at the run's last apex, at the
    scene's fine orbit settings (dop853, rtol 1e-13, dense landing, eps 1e-11). Slow: about 10 s."""
    import numpy as np

    from legsim.sweep.tasks import last_crossing

    fine = [
        "integrator.method=dop853",
        "integrator.rtol=1e-13",
        "integrator.atol=1e-13",
        "integrator.landing=dense",
        "integrator.eps=1e-11",
    ]
    problem = problem_from_scene(load_scene("quadruped_pronk_forward")).problem
    names = list(problem.memory_names)
    difference = []
    for t_final in (20, 30, 40):
        run = load_scene("quadruped_pronk_forward", [*fine, f"integrator.t_final={t_final}"]).simulate()
        assert run.status == "finished" and not run.warnings
        _, state = last_crossing(problem, run)
        memory = state[problem.dim :]
        difference.append(memory[names.index("bias_hind")] - memory[names.index("bias_front")])
    steps = np.diff(difference)
    # a steady drift of 1.8e-5 m every 10 s, each step within 25% of the other
    assert np.all(steps < -1.2e-5) and abs(steps[0] / steps[1] - 1.0) < 0.25
