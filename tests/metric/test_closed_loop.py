"""The quotient distance between two runs of a controlled system (legsim.metric.closed_loop), as
`legsim run --check-accuracy` reports it: equal to the metric's own value where the metric
takes the runs, first order in eps on the Raibert runners, larger for a perturbed run."""

import dataclasses
import json

import numpy as np
import pytest

from legsim.accuracy import quotient_distance
from legsim.cli import main
from legsim.metric import MetricError, distances, rho
from legsim.metric.closed_loop import _distances_at, comparison_times, plant_view, run_distance
from legsim.scene import load_scene
from legsim.systems import digital_control


def _run(scene, h, eps, dz=0.0):
    """The scene run with step h, strip width eps and its initial height raised by dz (m)."""
    scene = dataclasses.replace(scene, integrator={**scene.integrator, "h": h, "eps": eps})
    if dz:
        state = scene.initial_state.copy()
        state[1] += dz  # z, the second coordinate of both hoppers' flight state
        scene = dataclasses.replace(scene, initial_state=state)
    return scene.simulate()


def test_on_an_uncontrolled_run_it_is_the_metrics_rho_and_never_below_the_metric_at_a_time():
    # The ball's guard and reset have known shapes, so the metric's search is exact there (a
    # global minimum); up to just before its Zeno time every strip is a bounce's, which it takes.
    scene = load_scene("bouncing_ball", ["integrator.t_final=1.3"])
    run = scene.simulate()
    fine = _run(scene, scene.integrator["h"] / 2, scene.integrator["eps"] / 10)
    eps, system = scene.integrator["eps"], scene.model.system
    times = comparison_times(run, fine)
    exact = distances(system, run, fine, times, eps)
    ours, _ = _distances_at(
        system, plant_view(system, run), plant_view(system, fine), run.sample(times), fine.sample(times), eps, 2
    )
    # Each of ours is the length of a path that exists: never below the shortest.
    assert np.all(ours >= exact - 1e-12)
    result = run_distance(system, run, fine, eps)
    assert result.value == pytest.approx(rho(system, run, fine, times, eps), rel=1e-12)
    assert result.memory == {} and result.samples == times.size


@pytest.mark.parametrize("name", ["slip_raibert", "pronk_raibert"])
def test_on_a_raibert_runner_the_distance_is_first_order_in_eps(name):
    # 3 s: 5 (SLIP) or 10 (pronk) hops. At h = 2.5e-4 the flow's RK4 error is far below the
    # strips' delays, each transition late by up to eps over the guard's speed: O(eps).
    scene = load_scene(name, ["integrator.t_final=3"])
    reference = _run(scene, 2.5e-4, 1e-11)
    values = [
        run_distance(scene.model.system, _run(scene, 2.5e-4, eps), reference, eps).value for eps in (1e-5, 1e-6, 1e-7)
    ]
    slopes = np.diff(np.log10(values)) / np.diff(np.log10([1e-5, 1e-6, 1e-7]))
    assert np.all(np.abs(slopes - 1.0) < 0.1), (values, slopes)


def test_the_check_accuracys_distance_falls_tenfold_a_level_and_a_perturbed_run_is_far():
    # Levels (h, eps) -> (h/2, eps/10) as --check-accuracy refines: the eps term dominates, so
    # each level divides the distance by about 10 (between the eps factor 10 and h^4's 16 the
    # measured ratios are 9.5 to 10).
    scene = load_scene("slip_raibert", ["integrator.t_final=3"])
    system = scene.model.system
    levels = [(4e-3, 1e-6), (2e-3, 1e-7), (1e-3, 1e-8)]
    values = [run_distance(system, _run(scene, h, eps), _run(scene, h / 2, eps / 10), eps).value for h, eps in levels]
    assert values[0] / values[1] > 8 and values[1] / values[2] > 8, values
    # A run started 0.1 mm higher: the distance at t = 0 alone is 1e-4, and the hops drift apart.
    reference = _run(scene, 5e-4, 1e-8)
    nominal = run_distance(system, _run(scene, 1e-3, 1e-7), reference, 1e-7).value
    perturbed = run_distance(system, _run(scene, 1e-3, 1e-7, dz=1e-4), reference, 1e-7).value
    assert perturbed >= 1e-4 and perturbed > 100 * nominal


def test_the_memory_is_compared_entry_by_entry_in_its_own_units():
    scene = load_scene("slip_raibert", ["integrator.t_final=3"])
    run, fine = _run(scene, 1e-3, 1e-7), _run(scene, 5e-4, 1e-8)
    result = run_distance(scene.model.system, run, fine, 1e-7)
    assert set(result.memory) == set(scene.control.memory_names)  # T_s, t_touchdown, stance
    # The stance flag agrees wherever the modes do; the touchdown times differ by the runs' lag.
    lag = max(abs(a.time - b.time) for a, b in zip(run.transitions, fine.transitions, strict=True))
    assert result.memory["stance"] == 0.0 and result.memory["t_touchdown"] <= lag + 1e-12


def test_a_run_the_system_cannot_hold_is_refused_with_the_reason_not_a_crash():
    scene = load_scene("bouncing_ball", ["integrator.t_final=0.5"])
    run = scene.simulate()
    other_system = digital_control.make_system()
    with pytest.raises(MetricError, match="visits mode 'flight'"):
        run_distance(other_system, run, run, 1e-4)
    assert quotient_distance(other_system, run, run)[1].startswith("not defined: run visits mode 'flight'")
    assert quotient_distance(None, run, run) == (
        None,
        "not computed: the hybrid system the runs simulate was not given",
    )


def test_check_accuracy_prints_the_quotient_distance_in_text_and_json(capsys):
    args = ["run", "slip_raibert", "--check-accuracy", "--set", "integrator.t_final=3"]
    assert main([*args, "--json"]) == 0
    estimate = json.loads(capsys.readouterr().out)["error_estimate"]
    scene = load_scene("slip_raibert", ["integrator.t_final=3"])
    expected = run_distance(scene.model.system, _run(scene, 1e-3, 1e-7), _run(scene, 5e-4, 1e-8), 1e-7)
    assert estimate["quotient_distance"]["value"] == pytest.approx(expected.value, rel=1e-9)
    assert estimate["quotient_distance_note"] is None
    assert main(args) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "quotient distance (paper 000, plant" in x)
    assert f"{expected.value:.3g} at t = " in line and "memory apart" in line
