"""What ``simulate`` refuses, and what a run says when its controller or method cannot be taken as
given: a hand-built ``Tableau`` checked before it runs, conflicting step-size options, flags that
are not booleans, a controller's inputs that do not fit the plant or are left unwritten, and the
path a run took named by what made it take it."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import legsim.compiled  # noqa: F401 -- the kernel, so that runs are compiled
from helpers.compiled_models import above_floor
from legsim import HybridSystem, Mode, ModeFunctions, Transition, model_function
from legsim.control import ControlLaw, Controller
from legsim.errors import ModelError, SimulationError
from legsim.methods import Tableau
from legsim.methods.builtin import DORMAND_PRINCE, RK4, ROS34PW2
from legsim.relaxed import ErrorControl, FixedStep, simulate
from legsim.relaxed.watches import Watch
from legsim.systems import bouncing_ball
from legsim.systems import oscillator as osc

EX1 = osc.EXAMPLES["ex1"]


def oscillator():
    return osc.make_system(EX1["omega"], EX1["a"], EX1["x_max"], EX1["c"]), [EX1["x0"], EX1["xd0"]]


def ball_run(**options):
    system = bouncing_ball.make_system(restitution=0.8)
    return simulate(system, [1.0, 0.0], "flight", 1.0, 1e-3, 1e-5, **options)


@pytest.mark.parametrize(
    ("method", "says"),
    [
        (Tableau("short", 4, np.array([0.0, 1.0]), np.zeros((1, 1)), np.array([1.0])), "c must be finite numbers"),
        (Tableau("nan", 4, RK4.c, RK4.A, np.array([np.nan, 0.5, 0.25, 0.25])), "b must be finite numbers"),
        (Tableau("half", 1, np.array([0.0]), np.zeros((1, 1)), np.array([0.5])), "b must sum to 1"),
        (Tableau("err", 4, RK4.c, RK4.A, RK4.b, b_err=np.zeros(2), error_order=3), "b_err must be finite numbers"),
        (
            Tableau("upper", 2, np.array([0.0, 1.0]), np.array([[0.0, 1.0], [1.0, 0.0]]), np.array([0.5, 0.5])),
            "strictly lower triangular",
        ),
        (Tableau("fsal", 4, RK4.c, RK4.A, RK4.b, fsal=True), "fsal needs the last stage"),
        # The controller's exponent -1 / (error_order + 1) divided by zero at -1.
        (Tableau("order", 4, RK4.c, RK4.A, RK4.b, b_err=RK4.b, error_order=-1), "error_order must be an integer >= 1"),
        # Without G the linearly implicit stages ran to non_finite at t = 0, blaming the step.
        (dataclasses.replace(ROS34PW2, name="noG", G=None), "needs its stage coupling G"),
        # Its dense output was dropped while the run said landing "dense".
        (dataclasses.replace(ROS34PW2, name="rosdense", dense=DORMAND_PRINCE.dense), "takes no dense output"),
    ],
)
def test_a_hand_built_tableau_is_checked_before_it_runs(method, says):
    # Each of these ran before: with wrong physics (b summing to 1/2), or reading past its arrays.
    with pytest.raises(SimulationError, match=f"Tableau '{method.name}'.*{says}"):
        ball_run(method=method)


def test_every_built_in_method_passes_the_tableau_check():
    from legsim.methods.builtin import METHODS, get_method

    assert all(get_method(method) is method for method in METHODS.values())


@pytest.mark.parametrize(
    ("options", "says"),
    [
        ({"step_size": FixedStep(), "rtol": 1e-9}, "either step_size or rtol/atol"),
        ({"method": "dopri5", "step_size": ErrorControl(1e-3, 1e-6), "atol": 1e-12}, "either step_size or rtol/atol"),
        # Without tolerances the rule would run fixed steps while its name says error control.
        ({"method": "dopri5", "step_size": ErrorControl(None, None)}, "gives no tolerance: error control needs"),
        ({"python": "no"}, "python must be True or False"),
        ({"continuation": 1}, "continuation must be True or False"),
        ({"watches": 1}, "watches must be a sequence"),
        ({"t_eval": np.zeros((2, 2))}, "shape \\(2, 2\\)"),
    ],
)
def test_conflicting_or_mistyped_options_are_refused_by_name(options, says):
    with pytest.raises(SimulationError, match=says):
        ball_run(**options)


@pytest.mark.parametrize("python", [False, True])
def test_until_must_answer_true_or_false(python):
    with pytest.raises(SimulationError, match="until must return True or False, got str"):
        ball_run(until=lambda so_far: "no", python=python)


def test_a_single_watch_is_taken_as_one():
    # Below half a metre (the ball dropped from 1 m passes it at sqrt(1 / g) s): one warning.
    low = Watch("low", lambda mode, t, x: x[:, 0] - 0.5, action="warn", message=lambda t, mode, x: "below 0.5 m")
    ex = ball_run(watches=low)
    (warning,) = [w for w in ex.warnings if w.message.startswith("below 0.5 m")]
    assert warning.time == pytest.approx(math.sqrt(1.0 / 9.81), abs=1e-3)


def plain_forcing(t, x, m, p, u):
    u[0] = p[0] * math.cos(t)


@pytest.mark.parametrize("python", [False, True])
def test_a_control_law_of_plain_functions_runs_on_the_python_loop_and_says_why(python):
    system, x0 = oscillator()
    plain = ControlLaw("plain", plain_forcing, 1, lambda mode: np.ones(1))
    compiled = ControlLaw("compiled", model_function(plain_forcing), 1, lambda mode: np.ones(1))
    ran = simulate(system, x0, "free", 3.0, 1e-2, 1e-5, "rk4", plain, python=python)
    reference = simulate(system, x0, "free", 3.0, 1e-2, 1e-5, "rk4", compiled, python=True)
    assert ran.status == "finished" and ran.counters["compiled_steps"] == 0
    expected = "simulate(python=True)" if python else "controller plain has Python functions"
    assert expected in ran.settings["python_reason"]
    np.testing.assert_array_equal(ran.final_state, reference.final_state)


@model_function
def forgets_after_one_second(t, x, m, p, u):
    if t < 1.0:
        u[0] = 5.0


@pytest.mark.parametrize("python", [False, True])
def test_an_input_a_control_law_leaves_unwritten_ends_the_run_not_the_earlier_value(python):
    system, x0 = oscillator()
    law = ControlLaw("forgetful", forgets_after_one_second, 1, lambda mode: np.zeros(1))
    ex = simulate(system, x0, "free", 3.0, 1e-2, 1e-5, "rk4", law, python=python)
    assert ex.status == "non_finite" and ex.t_end == pytest.approx(1.0, abs=1e-2), ex.message


@pytest.mark.parametrize("inputs", [0, 3])
def test_a_control_law_giving_another_number_of_inputs_than_the_plant_takes_is_refused(inputs):
    system, x0 = oscillator()
    law = ControlLaw("misfit", forgets_after_one_second, inputs, lambda mode: np.zeros(1))
    with pytest.raises(ModelError, match=f"controller misfit gives {inputs} input entries, mode 'free' takes 1"):
        simulate(system, x0, "free", 1.0, 1e-2, 1e-5, "rk4", law)


@pytest.mark.parametrize("python", [False, True])
def test_a_python_control_returning_none_is_named_not_the_field(python):
    system, x0 = oscillator()
    with pytest.raises(ModelError, match="control returned None, expected 1 numbers"):
        simulate(system, x0, "free", 1.0, 1e-2, 1e-5, "rk4", lambda t, x: None, python=python)


@model_function
def falls(t, x, u, p, dx):
    dx[0] = x[1]
    dx[1] = -9.81


@model_function
def keep(e, t, x, u, p, out):
    out[0] = x[0]
    out[1] = x[1]


def test_a_mode_in_python_reached_later_is_named_as_the_reason_for_the_python_loop():
    # The run starts compiled in 'flight' and meets 'stance', written as Python callables, only
    # at the touchdown: the rest runs on the Python loop, and the run says that mode made it.
    system = HybridSystem(
        {
            "flight": Mode(2, names=("z", "zd"), functions=ModeFunctions(falls, above_floor, keep)),
            "stance": Mode(2, lambda t, x, u: np.array([x[1], 400.0 * (1.0 - x[0]) - 9.81]), names=("z", "zd")),
        },
        [
            Transition("flight", "stance", name="touchdown"),
            Transition("stance", "flight", guard=lambda x: max(1.0 - x[0], -x[1]), name="liftoff"),
        ],
        name="mixed",
    )
    ex = simulate(system, [1.2, 0.0], "flight", 1.0, 1e-3, 1e-6, "rk4")
    assert ex.status == "finished" and ex.counters["compiled_steps"] > 0 and ex.counters["python_steps"] > 0
    assert ex.settings["python_reason"] == "mode 'stance' is written as Python callables"


@pytest.mark.parametrize("action", ["stop", "warn", "time"])
def test_a_watch_that_gives_nan_is_refused_by_name_not_taken_as_never_holding(action):
    # nan < 0 is false: taken as it is, the watch would never hold and say nothing.
    def value(mode, t, x):
        return np.where(x[:, 0] < 0.5, np.nan, 1.0)  # unknown below half a metre

    told = {"counter": "unknown_s"} if action == "time" else {"message": lambda t, mode, x: "held"}
    watch = Watch("unknown", value, action=action, **told)
    with pytest.raises(SimulationError, match=r"watch 'unknown' gave nan for every part at t=0\.3"):
        ball_run(watches=[watch])


@model_function
def reset_to_nan(e, t, x, u, p, out):
    out[0] = x[0]
    out[1] = np.nan


def test_a_watch_on_a_run_whose_state_turns_nan_leaves_the_run_its_own_end():
    # The reset's image is nan: the run ends non_finite and says why; the watch, unknown there
    # as the state is, is not blamed for it.
    system = HybridSystem(
        {"air": Mode(2, names=("z", "zd"), functions=ModeFunctions(falls, above_floor, reset_to_nan))},
        [Transition("air", "air", name="bounce")],
        name="ball",
    )
    speed = Watch("fast", lambda mode, t, x: 100.0 - np.abs(x[:, 1]), action="warn", message=lambda t, m, x: "fast")
    ex = simulate(system, [1.0, 0.0], "air", 1.0, 1e-3, 1e-5, watches=[speed])
    assert ex.status == "non_finite" and "reset of transition bounce" in ex.message, ex.message


class NoInputOnTheGround(Controller):
    """A Python controller for a plant whose 'air' mode reads one input and 'ground' none."""

    def __call__(self, mode, t, x):
        return [0.0] if mode == "air" else None


@model_function
def rests(t, x, u, p, dx):
    dx[0] = 0.0
    dx[1] = 0.0


@model_function
def never(t, x, u, p, g):
    g[0] = 1.0


def test_a_python_control_may_return_none_in_a_mode_that_reads_no_input():
    pushed = ModeFunctions(falls_pushed, above_floor, keep, inputs=1)
    system = HybridSystem(
        {
            "air": Mode(2, names=("z", "zd"), functions=pushed),
            "ground": Mode(2, names=("z", "zd"), functions=ModeFunctions(rests, never, keep)),
        },
        [Transition("air", "ground", name="land"), Transition("ground", "air", name="lift")],
        name="drop",
    )
    ex = simulate(system, [1.0, 0.0], "air", 1.0, 1e-3, 1e-5, "rk4", NoInputOnTheGround())
    assert ex.status == "finished" and ex.final_mode == "ground"


@model_function
def falls_pushed(t, x, u, p, dx):
    dx[0] = x[1]
    dx[1] = -9.81 + u[0]
