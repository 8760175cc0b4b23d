"""Bad input to ``simulate`` and every ordinary failure of a run: each gives a legsim error (or a
run status) whose message names what is wrong, never a numpy traceback or a silent NaN."""

from __future__ import annotations

import numpy as np
import pytest

from legsim import HybridSystem, Mode, ModelError, SimulationError, Transition, simulate
from legsim.systems import bouncing_ball


def constant(v: float):
    return lambda t, x, u: np.array([v])


def one_mode(field, guard=None, reset=None) -> HybridSystem:
    transitions = [] if guard is None else [Transition("a", "a", guard, reset, name="edge")]
    return HybridSystem({"a": Mode(1, field, names=("q",))}, transitions, name="toy")


@pytest.fixture(scope="module")
def ball() -> HybridSystem:
    return bouncing_ball.make_system()


# -- invalid arguments: SimulationError naming the argument ----------------------------------
@pytest.mark.parametrize("h", [0.0, -1e-3, float("nan"), float("inf")])
def test_step_size_must_be_positive_and_finite(ball, h):
    with pytest.raises(SimulationError, match=r"^h must be finite and > 0, got"):
        simulate(ball, [1.0, 0.0], "flight", 1.0, h, 1e-3)


def test_step_size_must_be_a_number(ball):
    with pytest.raises(SimulationError, match=r"^h must be a number, got str '0.1'"):
        simulate(ball, [1.0, 0.0], "flight", 1.0, "0.1", 1e-3)


@pytest.mark.parametrize("eps", [0.0, -1.0, float("nan")])
def test_strip_width_must_be_positive(ball, eps):
    with pytest.raises(SimulationError, match=r"^eps must be finite and > 0, got"):
        simulate(ball, [1.0, 0.0], "flight", 1.0, 1e-3, eps)


@pytest.mark.parametrize("t_final", [0.0, -1.0, float("inf")])
def test_final_time_must_exceed_start(ball, t_final):
    with pytest.raises(SimulationError, match=r"^t_final must be finite and > t0 = 0.0, got"):
        simulate(ball, [1.0, 0.0], "flight", t_final, 1e-3, 1e-3)


def test_final_time_must_exceed_a_given_start(ball):
    with pytest.raises(SimulationError, match=r"^t_final must be finite and > t0 = 2.0, got 1.5"):
        simulate(ball, [1.0, 0.0], "flight", 1.5, 1e-3, 1e-3, t0=2.0)


def test_unknown_mode_lists_the_modes(ball):
    with pytest.raises(SimulationError, match=r"^unknown initial mode 'stance'; modes: \['flight', 'rest'\]"):
        simulate(ball, [1.0, 0.0], "stance", 1.0, 1e-3, 1e-3)


def test_mode_must_be_a_name(ball):
    with pytest.raises(SimulationError, match=r"^unknown initial mode 0; modes: \['flight', 'rest'\]"):
        simulate(ball, [1.0, 0.0], 0, 1.0, 1e-3, 1e-3)


@pytest.mark.parametrize("x0, shape", [([1.0, 0.0, 0.0], r"\(3,\)"), ([[1.0, 0.0]], r"\(1, 2\)"), (1.0, r"\(\)")])
def test_initial_state_shape_is_checked(ball, x0, shape):
    with pytest.raises(
        SimulationError,
        match=rf"^x0 has shape {shape}, expected \(2,\) for mode 'flight' "
        r"with coordinates \('z', 'zd'\)",
    ):
        simulate(ball, x0, "flight", 1.0, 1e-3, 1e-3)


def test_initial_state_must_be_numeric(ball):
    with pytest.raises(SimulationError, match=r"^x0 must be a numeric vector of length 2 for mode 'flight'"):
        simulate(ball, ["one", "two"], "flight", 1.0, 1e-3, 1e-3)


@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_initial_state_must_be_finite(ball, bad):
    with pytest.raises(SimulationError, match=r"^x0 must be finite, got .* in mode 'flight'"):
        simulate(ball, [1.0, bad], "flight", 1.0, 1e-3, 1e-3)


def test_initial_state_past_a_guard_by_more_than_eps(ball):
    # max(z, zd) = -0.01 < -eps: below the floor and falling.
    with pytest.raises(
        SimulationError,
        match=r"^x0 lies past the guard of transition bounce by 0.01 > eps = 0.001 "
        r"\(guard units\); start inside the domain of 'flight'",
    ):
        simulate(ball, [-0.01, -1.0], "flight", 1.0, 1e-3, 1e-3)


def test_initial_state_inside_the_strip_is_accepted_and_crosses_at_once(ball):
    ex = simulate(ball, [-5e-4, -1.0], "flight", 0.1, 1e-3, 1e-3)
    assert ex.status == "finished"
    first = ex.transitions[0]
    assert first.time == 0.0 and first.depth == pytest.approx(5e-4)
    np.testing.assert_allclose(first.state_after, [-5e-4, 0.5])  # the reset (z, -c zd), c = 0.5


def test_unknown_method_lists_the_choices(ball):
    with pytest.raises(
        SimulationError, match=r"^unknown method 'rk5'; choose one of \['bs32', 'dop853', 'dopri5', 'euler'"
    ):
        simulate(ball, [1.0, 0.0], "flight", 1.0, 1e-3, 1e-3, method="rk5")


def test_control_must_be_callable(ball):
    with pytest.raises(SimulationError, match=r"^control must be callable control\(t, x\) -> u or None, got float"):
        simulate(ball, [1.0, 0.0], "flight", 1.0, 1e-3, 1e-3, control=1.0)


def test_progress_must_be_callable(ball):
    message = r"^progress must be callable progress\(t, t0, t_final\) or None, got int 5"
    with pytest.raises(SimulationError, match=message):
        simulate(ball, [1.0, 0.0], "flight", 1.0, 1e-3, 1e-3, progress=5)


@pytest.mark.parametrize("value", [-1, 2.5, True])
def test_transition_budget_must_be_a_nonnegative_integer(ball, value):
    with pytest.raises(SimulationError, match=r"^max_transitions must be an integer >= 0, got"):
        simulate(ball, [1.0, 0.0], "flight", 1.0, 1e-3, 1e-3, max_transitions=value)


def test_system_must_be_a_hybrid_system():
    with pytest.raises(SimulationError, match=r"^system must be a legsim.HybridSystem, got dict"):
        simulate({"a": 1}, [1.0], "a", 1.0, 1e-3, 1e-3)


def test_field_of_wrong_shape_is_named_at_the_start():
    system = one_mode(lambda t, x, u: np.zeros(3))
    with pytest.raises(ModelError, match=r"^toy: field of mode 'a' returned shape \(3,\), expected \(1,\)"):
        simulate(system, [0.0], "a", 1.0, 0.1, 1e-3)


def test_failing_control_is_reported_as_a_legsim_error(ball):
    with pytest.raises(SimulationError, match="control"):
        simulate(ball, [1.0, 0.0], "flight", 1.0, 1e-3, 1e-3, control=lambda t, x: 1.0 / 0.0)


def test_field_failing_mid_run_is_reported_with_mode_and_time():
    system = one_mode(lambda t, x, u: np.array([1.0]) if x[0] < 0.5 else np.array(["oops"]))
    with pytest.raises(ModelError, match=r"mode 'a'.*t="):
        simulate(system, [0.0], "a", 1.0, 0.1, 1e-3)


# -- ordinary ends of a run: status and message ----------------------------------------------
def test_a_guard_that_jumps_past_the_strip_exhausts_the_halving():
    # The guard drops from +1 to -1 at q = 1: no step can land in its strip.
    system = one_mode(constant(1.0), guard=lambda x: 1.0 if x[0] < 1.0 else -1.0)
    ex = simulate(system, [0.0], "a", 3.0, 0.1, 1e-3)
    assert ex.status == "halving_exhausted"
    assert ex.message.startswith("no step from t=0.99999")
    assert "in mode 'a' lands in the relaxed domain (shortened " in ex.message
    # the guard's values at the step's start and at the last trial's end name the jump
    assert "the guard of transition edge goes from 1 to -1 within a rounding of t" in ex.message
    # Nothing past the guard was kept, and the run stops where the flow leaves.
    assert ex.t_end == pytest.approx(1.0, abs=1e-12)
    assert ex.final_state[0] < 1.0


def test_a_field_that_blows_up_ends_non_finite():
    # q' = q^2 from q(0) = 1 leaves every bounded set at t = 1.
    system = one_mode(lambda t, x, u: x * x)
    # The model overflows on purpose: its own overflow warnings are silenced.
    with np.errstate(over="ignore", invalid="ignore"):
        ex = simulate(system, [1.0], "a", 2.0, 0.01, 1e-3)
    assert ex.status == "non_finite"
    # The message names the mode, the time and the state.
    assert ex.message.startswith("the step from t=1.0") and "in mode 'a' gives a non-finite state" in ex.message
    assert f"x={ex.final_state.tolist()}" in ex.message
    # States stay finite (if huge) to within a couple of steps of the blow-up time.
    assert 1.0 <= ex.t_end < 1.03
    assert np.all(np.isfinite(ex.final_state))


def test_large_but_finite_states_are_not_called_non_finite():
    system = one_mode(constant(1e200))
    ex = simulate(system, [0.0], "a", 1.0, 0.25, 1e-3)
    assert ex.status == "finished"
    assert ex.final_state[0] == pytest.approx(1e200)


def test_a_nan_field_ends_non_finite_with_the_mode_named():
    system = one_mode(lambda t, x, u: np.array([1.0]) if x[0] < 0.5 else np.array([np.nan]))
    ex = simulate(system, [0.0], "a", 1.0, 0.1, 1e-3)
    assert ex.status == "non_finite"
    assert "mode 'a'" in ex.message
    assert ex.t_end <= 0.5 + 1e-12
    assert all(np.all(np.isfinite(s.x)) for s in ex.segments)


def test_a_reset_outside_the_target_domain_ends_the_run():
    system = HybridSystem(
        {"a": Mode(1, constant(1.0)), "b": Mode(1, constant(1.0))},
        [
            Transition("a", "b", lambda x: 1.0 - x[0], lambda x: np.array([-1.0]), name="jump"),
            Transition("b", "a", lambda x: x[0], name="back"),
        ],
        name="toy",
    )
    ex = simulate(system, [0.0], "a", 3.0, 0.1, 1e-3)
    assert ex.status == "reset_outside_domain"
    assert ex.message.startswith("state entering mode 'b' at t=1.00")
    assert "lies past the guard of transition back by 1 > eps=0.001: x=[-1.0]" in ex.message
    assert [tr.name for tr in ex.transitions] == ["jump"]


def test_the_transition_budget_ends_the_run(ball):
    ex = simulate(ball, [1.0, 0.0], "flight", 3.0, 1e-3, 1e-3, max_transitions=5)
    assert ex.status == "max_transitions"
    assert len(ex.transitions) == 5
    assert ex.message.startswith("transition budget max_transitions=5 used up at t=")
    assert "(next transition bounce from mode 'flight')" in ex.message
    # The sixth impact of the closed form is where the run stopped (to within 6 strip holds).
    t6 = bouncing_ball.BouncingBallReference().impact_time(6)
    assert ex.t_end == pytest.approx(float(t6), abs=6e-3)
    with pytest.raises(SimulationError, match=r"^simulation stopped with status 'max_transitions': transition"):
        ex.raise_for_status()


def test_a_step_below_the_time_resolution_is_refused(ball):
    # Near t = 1e15 float64 times are 0.125 s apart, so t + 1e-3 == t: no step can advance, and
    # the run must not pretend to have finished.
    with pytest.raises(SimulationError, match=r"h = 0.001 s is below the time resolution at t = 1e\+15 s"):
        simulate(ball, [1.0, 0.0], "flight", 1e15 + 2.0, 1e-3, 1e-4, t0=1e15)


def test_an_eps_below_float_resolution_is_refused_before_the_run(ball):
    with pytest.raises(SimulationError, match=r"^eps = 1e-300 is thinner than float64 resolves .* mode 'flight'"):
        simulate(ball, [1.0, 0.0], "flight", 1.0, 1e-3, 1e-300)
    # 16 spacings of float64 at the state's scale is the thinnest strip a step can land in.
    assert simulate(ball, [1.0, 0.0], "flight", 1.0, 1e-3, 1e-14).status == "finished"


def test_a_run_that_stops_advancing_ends_stalled_naming_mode_guard_and_time():
    # The reset puts its image at the strip's far edge (g = -eps): the next entry crosses at
    # once with depth tau = eps, so its strip lasts eps - tau = 0 s, and so on without end.
    eps = 1e-6
    system = HybridSystem(
        {"a": Mode(1, lambda t, x, u: np.array([1.0]))},
        [Transition("a", "a", lambda x: 1.0 - x[0], lambda x: np.array([1.0 + eps]), name="wall")],
    )
    ex = simulate(system, [0.0], "a", 10.0, 0.1, eps)
    assert ex.status == "stalled", ex.message
    assert "mode 'a'" in ex.message and "transition wall" in ex.message and f"t={ex.t_end:.17g}" in ex.message
    assert len(ex.transitions) < 2000 < 100_000  # ended by the stall rule, not the transition budget


def test_a_stall_of_the_error_control_away_from_guards_says_so_and_not_strip_advice():
    """A relay, x' = -sign(x): from x = 1 the flow reaches x = 0 at t = 1 s and slides there (a
    field that switches on the state, as a controller can). Error control shrinks the steps at
    the switch to rounding: the run stops ``stalled`` at t = 1 s, saying the field switches there
    with no guard near (the only guard, x = 10, is far), not that a thicker strip would help."""
    relay = HybridSystem(
        {"a": Mode(1, lambda t, x, u: np.array([-1.0 if x[0] > 0.0 else 1.0]), names=("x",))},
        [Transition("a", "a", lambda x: float(10.0 - x[0]), lambda x: np.zeros(1), name="wrap")],
    )
    ex = simulate(relay, [1.0], "a", 3.0, 0.1, 1e-6, "dop853", rtol=1e-12, atol=1e-12)
    assert ex.status == "stalled" and ex.t_end == pytest.approx(1.0, abs=1e-6)
    assert abs(ex.final_state[0]) < 1e-9
    assert "error control took the step down to" in ex.message and "sliding mode" in ex.message
    assert "next to the guard" not in ex.message and "thicker strip" not in ex.message


def test_a_step_budget_refuses_a_run_too_long_for_it(ball):
    with pytest.raises(
        SimulationError,
        match=r"^t_final - t0 = 1e\+12 s at h = 0.001 s is 1e\+15 steps, more than "
        r"max_steps = 10000000",
    ):
        simulate(ball, [1.0, 0.0], "flight", 1e12, 1e-3, 1e-3)


def test_an_error_controlled_run_ends_when_it_has_taken_its_step_budget(ball):
    # Nominally 10 steps of 0.1 s; the tolerance asks for many more: the budget ends the run
    # with its own status, the execution kept.
    ex = simulate(ball, [1.0, 0.0], "flight", 1.0, 0.1, 1e-6, "dopri5", rtol=1e-12, atol=1e-12, max_steps=20)
    assert ex.status == "max_steps" and ex.steps == 20 and 0.0 < ex.t_end < 1.0
    assert "step budget max_steps=20 used up" in ex.message


def test_progress_is_reported_across_transitions_when_no_step_is_taken(monkeypatch):
    # A Zeno ball past its accumulation point crosses strip after strip; progress must keep
    # coming by wall-clock time, not only every 64 steps of one mode visit.
    import legsim.relaxed.driver as run_module
    from legsim.systems import bouncing_ball as bb

    clock = iter(range(10**7))
    monkeypatch.setattr(run_module.time, "perf_counter", lambda: float(next(clock)))
    seen = []
    ex = simulate(
        bb.make_system(restitution=0.5),
        [1.0, 0.0],
        "flight",
        3.0,
        1e-2,
        1e-4,
        continuation=False,
        progress=lambda t, t0, t1: seen.append(t),
    )
    assert len(ex.transitions) > 640
    assert len(seen) >= len(ex.transitions) // 64 - 1


def test_a_failing_progress_callback_is_named_as_the_callers_not_the_models(ball, monkeypatch):
    import legsim.relaxed.driver as run_module

    def progress(t, t0, t1):
        raise RuntimeError("terminal closed")

    clock = iter(range(10**6))
    monkeypatch.setattr(run_module.time, "perf_counter", lambda: float(next(clock)))
    with pytest.raises(SimulationError, match=r"^the progress callback failed at t=.*RuntimeError: terminal closed"):
        simulate(ball, [1.0, 0.0], "flight", 2.0, 1e-3, 1e-3, progress=progress)


def test_a_progress_callback_stops_the_run_with_its_own_legsim_error(ball, monkeypatch):
    # A deadline (the sweep's --timeout) stops a run by raising its own LegsimError from the
    # callback: the caller must receive that error, not a SimulationError wrapping it.
    import legsim.relaxed.driver as run_module
    from legsim.errors import LegsimError

    class Deadline(LegsimError):
        pass

    def progress(t, t0, t1):
        if t > 0.5:
            raise Deadline(f"stopped at {t}")

    clock = iter(range(10**6))
    monkeypatch.setattr(run_module.time, "perf_counter", lambda: float(next(clock)))
    with pytest.raises(Deadline, match="stopped at"):
        simulate(ball, [1.0, 0.0], "flight", 2.0, 1e-3, 1e-3, progress=progress)


def test_scipys_adaptive_names_imply_error_control_with_scipys_default_tolerances(ball):
    adaptive = simulate(ball, [1.0, 0.0], "flight", 1.0, 0.1, 1e-3, "RK45")
    assert adaptive.settings["rtol"] == 1e-3 and adaptive.settings["atol"] == 1e-6
    fixed = simulate(ball, [1.0, 0.0], "flight", 1.0, 0.1, 1e-3, "dopri5")
    assert fixed.settings["rtol"] is None and fixed.settings["atol"] is None
    assert simulate(ball, [1.0, 0.0], "flight", 1.0, 0.1, 1e-3, "DOP853").settings["rtol"] == 1e-3


def test_t_eval_gives_the_states_at_those_times_in_one_call(ball):
    import math

    times = np.linspace(0.0, 0.4, 9)  # before the first impact at sqrt(2/g) = 0.4515 s
    ex = simulate(ball, [1.0, 0.0], "flight", 1.0, 1e-2, 1e-4, "rk4", t_eval=times)
    z = np.array(ex.evaluated.states)[:, 0]
    np.testing.assert_allclose(z, 1.0 - 0.5 * 9.81 * times**2, rtol=0, atol=1e-12)
    assert ex.evaluated.modes == ["flight"] * 9 and math.isclose(ex.evaluated.times[-1], 0.4)
    for unsorted in ([0.5, 0.2], [0.2, 0.2, 0.5]):  # a repeated time too, as solve_ivp refuses it
        with pytest.raises(SimulationError, match=r"t_eval must be finite, strictly increasing times in \[t0, t_final"):
            simulate(ball, [1.0, 0.0], "flight", 1.0, 1e-2, 1e-4, t_eval=unsorted)
