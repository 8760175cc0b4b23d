"""The run summary: what a recording stores is ``run_summary`` of the run, with the energies
at its start and end."""

from __future__ import annotations

import json

import numpy as np
import pytest

from legsim.output.summary import run_summary


def test_summary_round_trips_with_energies(hopper_run):
    model, ex, _, data = hopper_run
    s = data["summary"]
    base = run_summary(ex)
    for key, value in base.items():
        assert s[key] == value, key
    e = model.system.energy
    assert s["energy_initial"] == pytest.approx(e("flight", np.array([0.5, 0.0])), rel=1e-15)
    assert s["energy_final"] == pytest.approx(e(ex.final_mode, ex.final_state), rel=1e-15)
    # Lift-off with c = 0.9 loses energy: the recorded energies say so.
    assert s["energy_final"] < s["energy_initial"]
    assert s == json.loads(json.dumps(run_summary(ex, None, model)))


def test_execution_summary_is_the_run_summary(hopper_run):
    _, ex, _, _ = hopper_run
    s = run_summary(ex)
    assert s == run_summary(ex)
    assert s["transitions"] == len(ex.transitions) and s["mode_sequence"] == ex.mode_sequence
    assert "energy_initial" not in s and "scene" not in s and "outputs" not in s
    # Every counter of the run is in it, the integrator's and any other.
    assert all(key in s for key in ex.counters)


def test_scene_summary_names_the_scene_and_its_file(tmp_path):
    import legsim.record
    import legsim.scene
    from legsim.scene import load_scene

    scene = load_scene("bouncing_ball", overrides=["integrator.t_final=0.5"])
    ex = scene.simulate()
    s = run_summary(ex, scene, outputs={"rrd": tmp_path / "b.rrd"})
    assert (s["scene"], s["robot"], s["scene_file"]) == (scene.name, scene.robot, str(scene.path))
    assert s["energy_initial"] == pytest.approx(scene.energy(scene.initial_mode, scene.initial_state), rel=1e-15)
    assert s["outputs"] == {"rrd": str(tmp_path / "b.rrd")}
    assert scene.summary(ex) == {k: v for k, v in s.items() if k != "outputs"}
    # One function, under each of its public names.
    assert legsim.scene.run_summary is legsim.record.run_summary is run_summary


def test_numbers_that_are_not_finite_become_none(hopper_run):
    _, ex, _, _ = hopper_run
    ex.counters["odd_counter"] = float("nan")
    try:
        s = run_summary(ex)
    finally:
        del ex.counters["odd_counter"]
    assert s["odd_counter"] is None
    json.dumps(s, allow_nan=False)


def test_final_energy_of_a_stopped_run_may_fail_but_not_of_a_finished_one():
    from helpers.models import ball_model
    from legsim.builders import Model
    from legsim.errors import ModelError
    from legsim.hybrid import HybridSystem
    from legsim.relaxed import simulate

    ball = ball_model(c=0.5)

    def energy(mode, x):
        if x[0] < 0.5:
            raise OverflowError("too low")
        return 9.81 * x[0] + 0.5 * x[1] ** 2

    system = HybridSystem(ball.system.modes, ball.system.transitions, name="ball", energy=energy)
    model = Model(system, "flight", np.array([1.0, 0.0]))
    stopped = simulate(system, np.array([1.0, 0.0]), "flight", 5.0, 1e-3, 1e-3, max_transitions=1)
    assert stopped.status == "max_transitions"
    s = run_summary(stopped, None, model)
    assert s["energy_initial"] == pytest.approx(9.81) and s["energy_final"] is None
    finished = simulate(system, np.array([1.0, 0.0]), "flight", 1.0, 1e-3, 1e-3)
    with pytest.raises(ModelError, match=r"ball: energy in mode 'flight' failed: OverflowError: too low"):
        run_summary(finished, None, model)
