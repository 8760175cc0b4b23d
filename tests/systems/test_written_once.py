"""The analytic systems and the hoppers written once (``legsim.model``): every bundled scene of
theirs steps in the compiled kernel, and the same model functions run by the interpreted loop
give the same execution, point for point.

Both paths run one loop source over the same compiled functions, so their arithmetic is the
same operations in the same order: the executions agree to the last bit here, 1e-12 is the
bound asserted."""

import ast
from pathlib import Path

import numpy as np
import pytest

from helpers.compiled_scenes import SYSTEM_SCENES
from legsim import ModeFunctions, model_function
from legsim.compiled import native
from legsim.model import evaluate_field
from legsim.relaxed import driver
from legsim.scene import load_scene


def run(name: str, t_final: float | None = None):
    overrides = [] if t_final is None else [f"integrator.t_final={t_final!r}"]
    return load_scene(name, overrides).simulate()


@pytest.mark.parametrize("name", list(SYSTEM_SCENES))
def test_every_step_of_the_scene_is_compiled(name):
    ex = run(name)
    assert ex.counters["python_steps"] == 0 and ex.settings["path"] == "compiled"
    assert ex.counters["compiled_steps"] == ex.counters["steps"] > 0
    # Every one crosses guards (the grazing circle only touches its plane).
    assert ex.transitions or name == "grazing"


@pytest.mark.parametrize("name", list(SYSTEM_SCENES))
def test_the_interpreted_loop_gives_the_compiled_execution(monkeypatch, name):
    compiled = run(name, SYSTEM_SCENES[name])
    monkeypatch.setattr(driver, "KERNEL", None)
    interpreted = run(name, SYSTEM_SCENES[name])
    assert interpreted.counters["compiled_steps"] == 0 and interpreted.settings["path"] == "python"
    assert interpreted.status == compiled.status and interpreted.t_end == compiled.t_end
    counted = ("steps", "halvings", "field_evals", "guard_evals", "reset_evals", "transitions")
    assert [interpreted.counters[c] for c in counted] == [compiled.counters[c] for c in counted]
    assert [tr.name for tr in interpreted.transitions] == [tr.name for tr in compiled.transitions]
    for a, b in zip(interpreted.transitions, compiled.transitions, strict=True):
        assert abs(a.time - b.time) <= 1e-12 and abs(a.exit_time - b.exit_time) <= 1e-12
        np.testing.assert_allclose(a.state_after, b.state_after, rtol=0, atol=1e-12)
    assert len(interpreted.segments) == len(compiled.segments)
    for a, b in zip(interpreted.segments, compiled.segments, strict=True):
        assert a.mode == b.mode and a.t.shape == b.t.shape
        np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)


def test_two_tanks_switch_at_the_closed_form_times():
    # Each switch lags the exact one by the strip's hold, at most eps over the falling tank's
    # rate (0.5 m/s), and the lags add up.
    scene = load_scene("two_tanks")
    ex = scene.simulate()
    exact, modes = scene.reference.switching_times("q1", scene.initial_state, 12)
    times = np.array([tr.time for tr in ex.transitions[:12]])
    assert [tr.target for tr in ex.transitions[:12]] == modes
    eps, rate = 1e-3, 0.5
    assert np.all(np.abs(times - exact) <= np.arange(1, 13) * eps / rate)


def test_the_grazing_circle_stays_inside_on_the_rotation():
    # From (0, 1) the exact circle touches x1 = 1 without crossing it: the run stays inside,
    # on the rotation to RK4's error at h = 0.1 (~1e-6 over 3 s).
    scene = load_scene("grazing")
    ex = scene.simulate()
    assert ex.mode_sequence == ["inside"]
    exact = scene.reference.state(scene.initial_state, ex.t_end)
    np.testing.assert_allclose(ex.final_state, exact, atol=1e-5)


#: The controllers' modules and the laws they share: a plant's module imports none of them (a
#: controller is composed with its plant where the run is assembled).
CONTROLLER_MODULES = {
    "raibert",
    "raibert_pronk",
    "controllers",
    "hopper_laws",
    "control_laws",
    "runner_laws",
    "runner_layout",
    "stand_laws",
    "gait_changes",
}


@pytest.mark.parametrize("plant", ["slip_hopper.py", "pronk_hopper.py"])
def test_a_plants_module_imports_no_controller(plant):
    tree = ast.parse((Path(__file__).resolve().parents[2] / "robots" / plant).read_text())
    imported = {node.module or "" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    imported |= {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    assert {name.rsplit(".", 1)[-1] for name in imported} & CONTROLLER_MODULES == set()


@model_function
def _falling(t, x, u, p, dx):
    dx[0] = x[1]
    dx[1] = -p[0]


def test_calls_from_python_and_from_the_kernel_share_one_compiled_specialisation():
    # ModeFunctions keeps its params read-only. Handed to the function as they are, they would
    # make numba compile it, and everything it calls, a second time for a read-only p: tens of
    # seconds for a robot's bridge functions. A read-only state is copied for the same reason.
    functions = ModeFunctions(_falling, params=[9.81])
    assert not functions.params.flags.writeable
    x = np.array([1.0, 0.5])
    x.flags.writeable = False
    assert evaluate_field(functions, 2, 0.0, x, None).tolist() == [0.5, -9.81]
    native.address(_falling, "state")
    assert list(_falling.overloads) == [native.STATE_SIGNATURE.args]
