"""A compiled model function that raises mid-run fails the run on the compiled path as on the
Python loop, naming the mode and the time, instead of the run going on with whatever the
function left in its output (legsim/compiled/native.py passes the exception on); an output a
function leaves unwritten is nan, reported, never a value of an earlier call
(legsim/relaxed/evaluate.py, ``unwritten``)."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from helpers.compiled_models import above_floor, paddle, paddle_bounce
from legsim import HybridSystem, Mode, ModeFunctions, Transition, model_function, simulate
from legsim.control import ControlLaw, Controller
from legsim.errors import ModelError

G = 9.81


@model_function
def falls_until_half_a_metre(t, x, u, p, dx):
    if x[0] < 0.5:
        raise ValueError("below half a metre")
    dx[0] = x[1]
    dx[1] = -G


@model_function
def reads_past_its_parameters(t, x, u, p, dx):
    dx[0] = x[1]
    dx[1] = -G * p[2 * int(x[0] < 0.5)]  # p has two entries: index 2 is past its end below 0.5 m


def ball(field, params=(1.0, 0.5)):
    """A ball of ``field`` over a floor, bouncing back at half its speed (params: 1, restitution)."""
    return HybridSystem(
        {
            "air": Mode(
                2, names=("z", "zd"), functions=ModeFunctions(field, above_floor, paddle_bounce, params=list(params))
            )
        },
        [Transition("air", "air", name="bounce")],
        name="ball",
    )


@pytest.mark.parametrize("python", [False, True])
def test_a_raise_inside_a_model_function_fails_the_run_on_both_paths(python):
    # Dropped from 1 m, the ball passes 0.5 m at t = sqrt(2 * 0.5 / g) = 0.319 s.
    with pytest.raises(ModelError) as info:
        simulate(ball(falls_until_half_a_metre), [1.0, 0.0], "air", 2.0, 1e-3, 1e-4, "rk4", python=python)
    message = str(info.value)
    assert "mode 'air'" in message and "ValueError: below half a metre" in message, message
    t = float(message.split("from t=")[1].split(" ")[0])
    assert abs(t - np.sqrt(1.0 / G)) < 2e-3, message


@model_function
def refuses_hard_bounces(e, t, x, u, p, x_new):
    if x[1] < -1.0:
        raise ValueError("bounce too hard")
    x_new[0] = x[0]
    x_new[1] = -0.5 * x[1]


@model_function
def free_fall(t, x, u, p, dx):
    dx[0] = x[1]
    dx[1] = -G


@pytest.mark.parametrize("python", [False, True])
def test_the_message_names_the_function_that_raised_where_it_can(python):
    # The reset raises at the first bounce (4.4 m/s), not the field of the step it ends: the
    # Python source's traceback names it; compiled code leaves no frame of it, so the message
    # says how to find it.
    system = HybridSystem(
        {"air": Mode(2, functions=ModeFunctions(free_fall, above_floor, refuses_hard_bounces))},
        [Transition("air", "air", name="bounce")],
        name="ball",
    )
    with pytest.raises(ModelError) as info:
        simulate(system, [1.0, 0.0], "air", 2.0, 1e-3, 1e-6, "rk4", python=python)
    message = str(info.value)
    assert "ValueError: bounce too hard" in message, message
    if python:
        assert "raised in model function 'refuses_hard_bounces'" in message, message
    else:
        assert "python=True runs the model's Python source and names the function" in message, message


def test_an_index_past_the_end_is_caught_when_checked():
    """numba does not check indices unless asked: compiled with ``boundscheck=True`` (as
    docs/howto-compiled.md advises while a model is written), the index error fails the run."""
    checked = model_function(boundscheck=True)(reads_past_its_parameters.py_func)
    with pytest.raises(ModelError, match=r"mode 'air'.*IndexError"):
        simulate(ball(checked), [1.0, 0.0], "air", 2.0, 1e-3, 1e-4, "rk4")


@model_function
def writes_nothing(t, x, u, p, dx):
    pass


@model_function
def one_of_two_guards(t, x, u, p, g):
    g[0] = max(x[0], x[1])  # g[1], the second transition's, never written


@model_function
def fall(t, x, u, p, dx):
    dx[0] = x[1]
    dx[1] = -G


def two_transitions():
    return HybridSystem(
        {
            "air": Mode(
                2, names=("z", "zd"), functions=ModeFunctions(fall, one_of_two_guards, paddle_bounce, params=[1.0, 0.5])
            )
        },
        [Transition("air", "air", name="bounce"), Transition("air", "air", name="stick")],
        name="ball",
    )


@pytest.mark.parametrize("python", [False, True])
def test_an_output_a_model_function_leaves_unwritten_is_reported_not_used(python):
    """The loop fills a function's output with nan before the call: a field that writes nothing
    ends the run non-finite in its mode at once (it hovered, 'finished'), and a guard function
    that writes one of its mode's two guards ends it at the first evaluation (the second
    transition could never fire, silently)."""
    hover = simulate(ball(writes_nothing), [1.0, 0.0], "air", 1.0, 1e-3, 1e-4, "rk4", python=python)
    assert hover.status == "non_finite" and hover.t_end == 0.0 and "'air'" in hover.message, hover.message
    half = simulate(two_transitions(), [1.0, 0.0], "air", 1.0, 1e-3, 1e-4, "rk4", python=python)
    assert half.status == "non_finite" and half.t_end == 0.0
    assert half.message.startswith("guard of transition stick is nan at t=0 in mode 'air'"), half.message


class TwoInputs(Controller):
    """Returns two numbers for a plant that takes one: the controller's error, not the field's."""

    def __call__(self, mode, t, x):
        return np.array([0.0, 1.0])


class NoNumber(Controller):
    def __call__(self, mode, t, x):
        return "push"


@pytest.mark.parametrize(
    ("control", "says"),
    [
        (TwoInputs(), "controller TwoInputs returned 2 input entries, the plant takes 1"),
        (NoNumber(), "controller NoNumber returned str 'push', expected 1 numbers"),
        (lambda t, x: [1.0, 2.0, 3.0], "control returned 3 input entries, the plant takes 1"),
    ],
)
def test_a_python_controllers_input_of_the_wrong_size_is_named_as_the_controllers(control, says):
    """A compiled plant reads a Python controller's input as numbers: an input of another size or
    not numeric fails the run naming the controller, not the mode's field, where the loop
    writes the input."""
    system, _ = paddle()
    with pytest.raises(ModelError) as info:
        simulate(system, [1.0, 0.0], "flight", 0.5, 1e-3, 1e-6, "rk4", control=control)
    assert says in str(info.value) and "field" not in str(info.value)


@model_function
def past_its_range(t, x, u, p, dx):
    dx[0] = x[1]
    dx[1] = np.nan  # what a robot's contact dynamics write where no force is consistent


def into_a_mode_past_its_range(nan_breaks):
    """The ball's bounce leads into mode 'up', whose field is nan everywhere."""
    up = ModeFunctions(past_its_range, nan_breaks=nan_breaks, range_note="no consistent contact forces")
    return HybridSystem(
        {
            "air": Mode(
                2, names=("z", "zd"), functions=ModeFunctions(fall, above_floor, paddle_bounce, params=[1.0, 0.5])
            ),
            "up": Mode(2, names=("z", "zd"), functions=up),
        },
        [Transition("air", "up", name="bounce")],
        name="ball",
    )


@pytest.mark.parametrize("python", [False, True])
@pytest.mark.parametrize(("nan_breaks", "status"), [(True, "model_breakdown"), (False, "non_finite")])
def test_a_nan_at_a_mode_s_entry_is_a_breakdown_where_the_model_says_nan_breaks(python, nan_breaks, status):
    # Dropped from 1 m the ball enters 'up' at t = sqrt(2 / g); a model that declares nan_breaks
    # means by its nan a state past its range, at a mode's entry as inside a step.
    ex = simulate(into_a_mode_past_its_range(nan_breaks), [1.0, 0.0], "air", 1.0, 1e-3, 1e-4, "rk4", python=python)
    assert ex.status == status and ex.final_mode == "up", ex.message
    assert abs(ex.t_end - np.sqrt(2.0 / G)) < 2e-3
    assert ("no consistent contact forces" in ex.message) == nan_breaks, ex.message


@model_function
def guard_past_its_range(t, x, u, p, g):
    g[0] = np.nan


@pytest.mark.parametrize("python", [False, True])
def test_a_nan_guard_at_a_mode_s_entry_is_a_breakdown_where_the_model_says_nan_breaks(python):
    up = ModeFunctions(
        fall, guard_past_its_range, paddle_bounce, params=[1.0, 0.5], nan_breaks=True, range_note="guard past its range"
    )
    system = HybridSystem(
        {
            "air": Mode(
                2, names=("z", "zd"), functions=ModeFunctions(fall, above_floor, paddle_bounce, params=[1.0, 0.5])
            ),
            "up": Mode(2, names=("z", "zd"), functions=up),
        },
        [Transition("air", "up", name="bounce"), Transition("up", "air", name="back")],
        name="ball",
    )
    ex = simulate(system, [1.0, 0.0], "air", 1.0, 1e-3, 1e-4, "rk4", python=python)
    assert ex.status == "model_breakdown" and ex.final_mode == "up" and "guard past its range" in ex.message


@model_function
def pushed_down(t, x, u, p, dx):
    dx[0] = x[1]
    dx[1] = -G + u[0]


@model_function
def forgets_at_the_floor(t, x, m, p, u):
    if x[0] > 0.5:
        u[0] = 0.0  # below half a metre the law writes nothing


@pytest.mark.parametrize("python", [False, True])
@pytest.mark.parametrize("nan_breaks", [False, True])
def test_an_input_a_law_leaves_unwritten_is_named_whatever_the_model_s_nan_means(python, nan_breaks):
    from legsim.control import ControlLaw

    functions = ModeFunctions(
        pushed_down, above_floor, paddle_bounce, params=[1.0, 0.5], inputs=1, nan_breaks=nan_breaks
    )
    system = HybridSystem({"air": Mode(2, names=("z", "zd"), functions=functions)}, [Transition("air", "air")])
    law = ControlLaw("forgetful", forgets_at_the_floor, 1, lambda mode: np.zeros(0))
    ex = simulate(system, [1.0, 0.0], "air", 1.0, 1e-3, 1e-4, "rk4", law, python=python)
    assert ex.status == "non_finite" and "controller's input u=[nan]" in ex.message, ex.message
    assert abs(ex.t_end - np.sqrt(1.0 / G)) < 2e-3


def _probe_system(field=None, guards=None, reset=None, params=(), inputs=0):
    @model_function
    def drift(t, x, u, p, dx):
        dx[0] = 1.0

    @model_function
    def wall(t, x, u, p, g):
        g[0] = 1.0 - x[0]

    @model_function
    def keep(e, t, x, u, p, out):
        out[0] = x[0]

    functions = ModeFunctions(field or drift, guards or wall, reset or keep, params=list(params), inputs=inputs)
    modes = {"A": Mode(1, functions=functions), "B": Mode(1, functions=ModeFunctions(drift))}
    return HybridSystem(modes, [Transition("A", "B", name="ab")])


@model_function
def _writes_past_dx(t, x, u, p, dx):
    dx[0] = 1.0
    dx[1] = 1.0


@model_function
def _reads_past_p(t, x, u, p, dx):
    dx[0] = p[3]


@model_function
def _reads_an_input_it_lacks(t, x, u, p, dx):
    dx[0] = u[0]


@model_function
def _two_guards(t, x, u, p, g):
    g[0] = 1.0 - x[0]
    g[1] = 2.0 - x[0]


@model_function
def _reset_past_target(e, t, x, u, p, out):
    out[0] = x[0]
    out[1] = 0.0


@pytest.mark.parametrize("python", [False, True], ids=["compiled", "interpreted"])
@pytest.mark.parametrize(
    ("kwargs", "what"),
    [
        ({"field": _writes_past_dx}, "its field (_writes_past_dx)"),
        ({"field": _reads_past_p, "params": [1.0]}, "its field (_reads_past_p)"),
        ({"field": _reads_an_input_it_lacks}, "its field (_reads_an_input_it_lacks)"),
        ({"guards": _two_guards}, "its guards (_two_guards)"),
        ({"reset": _reset_past_target}, "its reset 0 (_reset_past_target)"),
    ],
)
def test_a_compiled_function_indexing_past_its_arrays_is_refused_before_it_runs(python, kwargs, what):
    """numba does not check indices: compiled, each of these ran to `finished` on memory that is
    not the model's (a read of p[3] came back 0, of u[0] 1e-309). Each mode's functions are run
    once as Python before the run, which raises where they index past an array."""
    with pytest.raises(ModelError, match=rf"mode 'A': {re.escape(what)} indexes past an array"):
        simulate(_probe_system(**kwargs), [0.0], "A", 2.0, 0.1, 1e-4, "rk4", python=python)


def test_a_refused_model_is_refused_again_on_every_run():
    """The probe's verdict is kept only for functions that passed: the same system, run again
    after its refusal, must not run compiled on memory that is not its own."""
    system = _probe_system(field=_reads_an_input_it_lacks)
    for _ in range(2):
        with pytest.raises(ModelError, match="indexes past an array"):
            simulate(system, [0.0], "A", 2.0, 0.1, 1e-4, "rk4")


@model_function
def _pushes_by_second_gain(t, x, m, p, u):
    u[0] = p[1]


@model_function
def _drift_by_input(t, x, u, p, dx):
    dx[0] = u[0]


@pytest.mark.parametrize("python", [False, True], ids=["compiled", "interpreted"])
def test_a_controller_reading_past_its_parameters_is_refused_on_both_paths(python):
    """A controller whose params(mode) has one entry but reads p[1]: compiled, it ran to
    `finished` on whatever lay past its parameters, while the Python loop raised IndexError."""
    law = ControlLaw("short gains", _pushes_by_second_gain, 1, lambda mode: np.array([3.0]))
    system = _probe_system(field=_drift_by_input, inputs=1)
    with pytest.raises(ModelError, match=r"mode 'A': its controller's control \(_pushes_by_second_gain\) indexes"):
        simulate(system, [0.0], "A", 2.0, 0.1, 1e-4, "rk4", law, python=python)


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ([[1.0, 2.0], [3.0, 4.0]], r"params must be a flat sequence of numbers, got shape \(2, 2\)"),
        (["a"], "params must be numbers"),
    ],
)
def test_params_that_are_not_a_flat_sequence_of_numbers_are_refused(params, message):
    """A table of parameters was flattened, its rows run together, and the run went on with them."""
    with pytest.raises(ModelError, match=message):
        ModeFunctions(_reads_past_p, params=params)
    assert ModeFunctions(_reads_past_p, params=np.arange(4.0)).params.shape == (4,)


def test_a_mode_given_both_a_field_and_functions_is_refused():
    """simulate evaluates the functions; a field beside them (here g = 1 against the functions'
    9.81) was silently ignored by the run while the tools reading Mode.field used it."""
    with pytest.raises(ModelError, match="Mode takes a field or functions, not both"):
        Mode(2, lambda t, x, u: np.array([x[1], -1.0]), functions=ModeFunctions(free_fall, above_floor, paddle_bounce))
    mode = Mode(2, functions=ModeFunctions(free_fall, above_floor, paddle_bounce))
    renamed = dataclasses.replace(mode, names=("z", "zd"))  # the field made from the functions passes back
    assert renamed.functions is mode.functions and renamed.names == ("z", "zd")


@model_function
def _joint_returning_two(rest, t, q, u, p, crossed, out):
    for d in range(4):
        out[d] = q[d]
    return 2


@pytest.mark.parametrize("python", [False, True], ids=["compiled", "interpreted"])
def test_a_joint_outcome_past_the_modes_outcomes_fails_the_run_at_the_crossing(python):
    """Index 2 of one outcome would take another mode's joint row as the target; the run went on
    to its end and failed in the execution's assembly with a bare IndexError."""
    from helpers.compiled_models import G, both_bounce, two_bounces, two_falls, two_floors

    functions = ModeFunctions(two_falls, two_floors, two_bounces, _joint_returning_two, params=[G, 0.6],
                              joint_outcomes=(("joint_bounce", "falling"),))  # fmt: skip
    transitions = [Transition("falling", "falling", name="bounce_1"), Transition("falling", "falling", name="bounce_2")]
    system = HybridSystem({"falling": Mode(4, functions=functions)}, transitions, name="two balls")
    # Dropped together from 1 m, both balls strike at t = sqrt(2 / g) = 0.4515 s.
    with pytest.raises(ModelError, match=r"from t=0\.4515.*index past its mode's joint_outcomes"):
        simulate(system, [1.0, 1.0, 0.0, 0.0], "falling", 2.0, 1e-3, 1e-6, "rk4", python=python)
    with pytest.raises(ModelError, match=r"ModeFunctions\.joint needs joint_outcomes"):
        ModeFunctions(two_falls, two_floors, two_bounces, both_bounce, params=[G, 0.6])
