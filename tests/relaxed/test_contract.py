"""The model's contract checked at every evaluation during a run, not only on the initial state:
a guard that is not a real number and a field whose output changes shape end the run with a
ModelError naming the mode, the transition and the time."""

import numpy as np
import pytest

from legsim import HybridSystem, Mode, ModelError, Transition, simulate


def ball(guard, field=None):
    field = field or (lambda t, x, u: np.array([x[1], -9.81]))
    return HybridSystem(
        {"fly": Mode(2, field, names=("z", "zd"))},
        [Transition("fly", "fly", guard, lambda x: np.array([x[0], -0.5 * x[1]]), name="bounce")],
    )


def test_a_guard_that_turns_boolean_mid_run_is_a_model_error_naming_it():
    # A comparison in place of a distance: a float at first, then a bool; float(False) would be
    # 0, never past the floor, and the ball would fall through it with no transition.
    def guard(x):
        return float(x[0]) if x[0] > 0.5 else bool(x[0] > 0.0)

    with pytest.raises(
        ModelError,
        match=r"guard of transition bounce must return a real number \(a float\), got "
        r"bool True in the step from t=0\.3.* in mode 'fly'",
    ):
        simulate(ball(guard), [1.0, 0.0], "fly", 2.0, 1e-2, 1e-3)


@pytest.mark.parametrize("bad", [None, np.array([0.2, 0.1])])
def test_a_guard_that_returns_none_or_an_array_is_refused_before_the_run(bad):
    with pytest.raises(ModelError, match="guard of transition bounce must return"):
        simulate(ball(lambda x: bad), [1.0, 0.0], "fly", 2.0, 1e-2, 1e-3)


def test_a_field_that_changes_shape_mid_run_is_a_model_error_naming_it():
    # From t = 0.25 s the field returns one component: broadcast into the step, it would move z
    # by zd's rate and sink the ball under the floor.
    def field(t, x, u):
        return np.array([x[1], -9.81]) if t < 0.25 else np.array([-9.81])

    with pytest.raises(
        ModelError,
        match=r"field returned shape \(1,\), expected \(2,\) in the step from "
        r"t=0\.2.* in mode 'fly'",
    ):
        simulate(ball(lambda x: max(x[0], x[1]), field), [1.0, 0.0], "fly", 2.0, 1e-2, 1e-3)


@pytest.mark.parametrize("method", ["euler", "rk4", "dopri5"])
def test_the_shape_check_covers_every_stage_and_the_step_end(method):
    calls = {"n": 0}

    def field(t, x, u):
        calls["n"] += 1
        return np.array([x[1], -9.81]) if calls["n"] < 40 else np.array([x[1], -9.81, 0.0])

    with pytest.raises(ModelError, match=r"field returned shape \(3,\), expected \(2,\)"):
        simulate(ball(lambda x: max(x[0], x[1]), field), [1.0, 0.0], "fly", 2.0, 1e-2, 1e-3, method)
