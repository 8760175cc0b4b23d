"""The compiled step loop (legsim.compiled) against the Python loop it replaces.

The kernel performs the same floating-point operations in the same order as the Python
stepper, so the two paths must give the same execution: the same transitions at the same times
and the same stored points, to 1e-12 (in practice bit for bit), with the same counters."""

import math

import numba
import numpy as np
import pytest

import legsim.compiled as compiled
import legsim.compiled.visit as compiled_visit
import legsim.relaxed.run as run_module
from legsim import HybridSystem, Mode, ModelError, Transition, simulate
from legsim.compiled import CompiledMode, plan_for, without_compiled
from legsim.compiled.generate import importable
from legsim.errors import ModelBreakdown
from legsim.methods import METHODS, get_method
from legsim.systems.fast import make_bouncing_ball, make_oscillator, make_oscillator_example
from legsim.systems.oscillator import OscillatorReference

COUNTERS = ("steps", "halvings", "error_rejections", "field_evals", "guard_evals", "reset_evals", "transitions")


def assert_same_execution(a, b, tol=1e-12):
    assert a.status == b.status
    assert a.message == b.message
    assert len(a.transitions) == len(b.transitions)
    for ta, tb in zip(a.transitions, b.transitions, strict=True):
        assert ta.name == tb.name
        assert abs(ta.time - tb.time) <= tol and abs(ta.exit_time - tb.exit_time) <= tol
        assert np.allclose(ta.state_before, tb.state_before, rtol=0, atol=tol)
        assert np.allclose(ta.state_after, tb.state_after, rtol=0, atol=tol, equal_nan=True)
    assert len(a.segments) == len(b.segments)
    for sa, sb in zip(a.segments, b.segments, strict=True):
        assert sa.t.shape == sb.t.shape
        assert np.allclose(sa.t, sb.t, rtol=0, atol=tol)
        scale = max(1.0, np.nanmax(np.abs(sb.x)))
        assert np.allclose(sa.x, sb.x, rtol=0, atol=tol * scale, equal_nan=True)
        assert np.allclose(sa.dx, sb.dx, rtol=0, atol=tol * max(1.0, np.nanmax(np.abs(sb.dx))), equal_nan=True)
    assert len(a.strips) == len(b.strips)
    for pa, pb in zip(a.strips, b.strips, strict=True):
        assert pa.name == pb.name and abs(pa.time - pb.time) <= tol and abs(pa.exit_time - pb.exit_time) <= tol
    assert a.final_in_strip == b.final_in_strip and a.t_end == pytest.approx(b.t_end, abs=tol)
    assert abs(a.counters["strip_time"] - b.counters["strip_time"]) <= tol * max(1, len(a.strips))
    for key in COUNTERS:
        assert a.counters[key] == b.counters[key], key


def both_paths(system, x0, mode, t_final, h, eps, method, **kw):
    fast = simulate(system, x0, mode, t_final, h, eps, method, **kw)
    slow = simulate(without_compiled(system), x0, mode, t_final, h, eps, method, **kw)
    return fast, slow


@pytest.mark.parametrize("landing", ["halve", "aim"])
@pytest.mark.parametrize("method,tols", [("rk4", {}), ("euler", {}), ("bs32", {"rtol": 1e-7, "atol": 1e-9})])
def test_oscillator_example1_same_on_both_paths(method, tols, landing):
    system, x0, _ = make_oscillator_example("ex1")
    fast, slow = both_paths(system, x0, "free", 12.0, 2e-2, 1e-5, method, landing=landing, **tols)
    assert len(fast.transitions) >= 4  # the comparison covers impacts, not only free flight
    assert_same_execution(fast, slow)


@pytest.mark.parametrize("landing", ["halve", "aim"])
@pytest.mark.parametrize("method,tols", [("rk2", {}), ("dopri5", {"rtol": 1e-8, "atol": 1e-10})])
def test_bouncing_ball_zeno_same_on_both_paths(method, tols, landing):
    # Past the Zeno time the strips chain: many transitions, each with shortened steps.
    system = make_bouncing_ball(9.81, 0.5)
    # The plain relaxed semantics (no continuation): the kernel crosses the chain of strips.
    fast, slow = both_paths(
        system,
        [1.0, 0.0],
        "flight",
        2.0,
        1e-2,
        1e-4,
        method,
        landing=landing,
        continuation=False,
        max_transitions=300,
        **tols,
    )
    zeno = math.sqrt(2 / 9.81) * 3  # t1 (1 + 2c / (1 - c)) with c = 0.5
    assert len(fast.transitions) > 20 and fast.transitions[-1].time > zeno - 0.05
    assert_same_execution(fast, slow)


def test_oscillator_example2_sticking_same_on_both_paths():
    system, x0, _t_max = make_oscillator_example("ex2")
    fast, slow = both_paths(
        system, x0, "free", 0.5, 1e-2, 1e-5, "rk4", landing="aim", max_transitions=400, continuation=False
    )
    assert len(fast.transitions) > 20  # the mass sticks: a stream of strip crossings
    assert_same_execution(fast, slow)


@pytest.mark.parametrize("which", ["ball", "ex2"])
def test_continuation_at_an_accumulation_is_the_same_on_both_paths(which):
    # By default accumulating impacts continue in the resting/sticking mode: these twins do not
    # compute the continuation's reset, so the kernel hands an accumulating crossing to Python.
    if which == "ball":
        system, x0, mode, t_final = make_bouncing_ball(9.81, 0.5), [1.0, 0.0], "flight", 2.0
    else:
        system, x0, _ = make_oscillator_example("ex2")
        mode, t_final = "free", 8.0
    fast, slow = both_paths(system, x0, mode, t_final, 1e-2, 1e-5, "rk4", landing="aim")
    assert any(tr.name in ("rest", "stick") for tr in fast.transitions)
    assert_same_execution(fast, slow)


def test_long_free_flight_grows_the_buffer_and_matches_the_closed_form():
    # No stop: one segment of 4000 points (the buffer starts at 256) and no guards at all.
    system = make_oscillator(2.5, 0.05, None, 0.9, 1.0, 20.0, 2.5)
    fast, slow = both_paths(system, [1.0, 0.0], "free", 40.0, 1e-2, 1e-3, "rk4")
    assert_same_execution(fast, slow)
    assert len(fast.segments[0].t) == 4001
    ref = OscillatorReference(2.5, 0.05, None, 0.9, 1.0, 20.0, 2.5, 1.0, 0.0)
    # RK4 at h = 1e-2 on frequencies 2.5 rad/s: global error ~ (omega h)^4 t * amplitude.
    assert abs(fast.final_state - ref.state(40.0)).max() < 1e-5


def test_compiled_path_is_taken_only_without_control(monkeypatch):
    calls = []
    real = compiled.enter_compiled

    def spy(run, mode, x, t):
        calls.append(mode)
        return real(run, mode, x, t)

    monkeypatch.setattr(compiled, "enter_compiled", spy)
    system = make_bouncing_ball()
    simulate(system, [1.0, 0.0], "flight", 0.3, 1e-2, 1e-4)  # before the first impact: one visit
    assert calls == ["flight"]
    simulate(system, [1.0, 0.0], "flight", 0.3, 1e-2, 1e-4, control=lambda t, x: None)
    assert calls == ["flight"]


def test_progress_is_reported_from_the_compiled_loop(monkeypatch):
    clock = iter(np.arange(0.0, 1e6, 1.0))  # every reading one second later than the last
    monkeypatch.setattr(run_module.time, "perf_counter", lambda: float(next(clock)))
    monkeypatch.setattr(compiled_visit, "PROGRESS_CHUNK", 100)
    seen = []
    system = make_oscillator(2.5, 0.05, None, 0.9, 1.0, 20.0, 2.5)
    ex = simulate(
        system, [1.0, 0.0], "free", 10.0, 1e-2, 1e-3, "rk4", progress=lambda t, t0, t1: seen.append((t, t0, t1))
    )
    assert ex.status == "finished"
    # 1000 steps; the kernel returns after at most 100 steps or when the buffer fills, and each
    # return after a full chunk is reported (the fake clock always says a second has passed).
    times = [t for t, _, _ in seen]
    assert len(times) >= 5 and np.diff(np.concatenate([[0.0], times, [10.0]])).max() <= 2.0 + 1e-9
    assert np.all(np.diff(times) > 0) and 0 < times[0] <= 1.0 + 1e-9 and times[-1] < 10.0
    assert np.allclose(np.array(times) * 100, np.round(np.array(times) * 100), atol=1e-6)  # on the step grid
    assert all(t0 == 0.0 and t1 == 10.0 for _, t0, t1 in seen)


# A probe twin for the failure paths: field (p0 x0^2 + p1 x1, p2); guard selected by p3:
# 0 smooth (p4 - x0), 1 a jump from +1 to -1 at x0 = p4, 2 nan beyond p4; reset x0 -> p5.
@numba.njit(cache=True)
def probe_field(t, x, p):
    out = np.empty(2)
    out[0] = p[0] * x[0] * x[0] + p[1] * x[1]
    out[1] = p[2]
    return out


@numba.njit(cache=True)
def probe_guards(x, p):
    out = np.empty(1)
    if p[3] == 0.0:
        out[0] = p[4] - x[0]
    elif p[3] == 1.0:
        out[0] = 1.0 if x[0] < p[4] else -1.0
    else:
        out[0] = 1.0 if x[0] < p[4] else math.nan
    return out


@numba.njit(cache=True)
def probe_resets(x, p, e):
    out = np.empty(2)
    out[0] = p[5]
    out[1] = x[1]
    return out


def probe_system(p, n_guards=1, guard_py=None, reset_py=None):
    p = np.asarray(list(p) + [0.0] * (6 - len(p)), dtype=float)

    def field(t, x, u):
        return np.array([p[0] * x[0] * x[0] + p[1] * x[1], p[2]])

    def guard(x):
        if p[3] == 0.0:
            return p[4] - x[0]
        if p[3] == 1.0:
            return 1.0 if x[0] < p[4] else -1.0
        return 1.0 if x[0] < p[4] else math.nan

    twin = CompiledMode(probe_field, probe_guards, n_guards, p, probe_resets)
    return HybridSystem(
        {"m": Mode(2, field, compiled=twin)},
        [Transition("m", "m", guard_py or guard, reset_py or (lambda x: np.array([p[5], x[1]])), name="wrap")],
    )


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # numpy warns on the Python path as x overflows
def test_non_finite_state_ends_both_paths_alike():
    # x' = x^2 from x = 1 blows up at t = 1; the guard is out of reach.
    fast, slow = both_paths(probe_system([1.0, 0.0, 0.0, 0.0, 1e300]), [1.0, 0.0], "m", 2.0, 1e-2, 1e-3, "rk4")
    assert fast.status == "non_finite" and "non-finite state" in fast.message
    assert_same_execution(fast, slow)


def test_discontinuous_guard_exhausts_halving_on_both_paths():
    # x0 moves at unit speed; the guard jumps from +1 to -1 at x0 = 0.5: no step can land in the strip.
    fast, slow = both_paths(
        probe_system([0.0, 1.0, 0.0, 1.0, 0.5]), [0.0, 1.0], "m", 2.0, 1e-2, 1e-3, "rk4", max_halvings=20
    )
    assert fast.status == "halving_exhausted" and "transition wrap" in fast.message
    assert_same_execution(fast, slow)


def test_a_strip_too_thin_for_float64_gives_the_same_message_on_both_paths():
    # eps = 1e-300 m: no step can land in the ball's strip. Both paths end with the one message
    # the shared message builder makes, naming the transition and float64's resolution.
    system = make_bouncing_ball(9.81, 0.5)
    fast, slow = both_paths(system, [1.0, 0.0], "flight", 1.0, 1e-2, 1e-300, "rk4")
    assert fast.status == "halving_exhausted"
    assert "thinner than float64 can resolve" in fast.message
    assert_same_execution(fast, slow)


def test_nan_guard_ends_both_paths_alike():
    fast, slow = both_paths(probe_system([0.0, 1.0, 1.0, 2.0, 0.5]), [0.0, 0.0], "m", 2.0, 1e-2, 1e-3, "rk4")
    assert fast.status == "non_finite" and "guard of transition wrap is nan" in fast.message
    assert_same_execution(fast, slow)


def test_twin_that_disagrees_with_the_python_model_is_refused():
    # The Python guard is shifted by 0.1 from the twin's: the check at the first visit catches it.
    system = probe_system([0.0, 1.0, 1.0, 0.0, 0.5], guard_py=lambda x: 0.6 - x[0])
    with pytest.raises(ModelError, match="compiled twin of mode 'm' disagrees with the Python callables"):
        simulate(system, [0.0, 0.0], "m", 1.0, 1e-2, 1e-3)


def test_a_reset_past_its_models_range_at_the_first_visit_does_not_end_the_run():
    # The check at a mode's first visit compares the resets there too. A Python reset that
    # raises a ModelBreakdown at that state (where no run applies it) is skipped: the Python
    # path never calls it there, and both paths run on to the guard and wrap.
    p = [0.0, 1.0, 1.0, 0.0, 0.5, 0.2]

    def wrap(x):
        if x[0] < 0.1:
            raise ModelBreakdown("wrapped before x0 = 0.1")
        return np.array([p[5], x[1]])

    probe = probe_system(p)
    system = HybridSystem(
        {"a": Mode(2, lambda t, x, u: np.array([x[1], 1.0])), "m": probe.modes["m"]},
        [
            Transition("a", "m", lambda x: 0.05 - x[0], None, name="enter"),
            Transition("m", "m", lambda x: p[4] - x[0], wrap, name="wrap"),
        ],
    )
    fast, slow = both_paths(system, [0.0, 0.0], "a", 1.5, 1e-2, 1e-3, "rk4")
    assert fast.status == "finished" and [t.name for t in fast.transitions][:2] == ["enter", "wrap"]
    assert_same_execution(fast, slow)


def test_twin_with_the_wrong_guard_count_is_refused():
    with pytest.raises(ModelError, match="declares 2 guards, the mode has 1 outgoing transitions"):
        simulate(probe_system([0.0, 1.0, 1.0, 0.0, 0.5], n_guards=2), [0.0, 0.0], "m", 1.0, 1e-2, 1e-3)
    with pytest.raises(ModelError, match="n_guards must be an integer >= 0"):
        CompiledMode(probe_field, probe_guards, -1)


def test_transitions_crossed_in_the_kernel_in_several_record_batches(monkeypatch):
    # Sticking in Example 2 crosses hundreds of strips inside the kernel; with batches of 16
    # records Python assembles them in many rounds, and the execution must not change.
    monkeypatch.setattr(compiled_visit, "RECORD_CHUNK", 16)
    system, x0, _ = make_oscillator_example("ex2")
    fast, slow = both_paths(system, x0, "free", 1.0, 1e-2, 1e-5, "rk4", landing="halve", continuation=False)
    assert len(fast.transitions) > 100
    assert_same_execution(fast, slow)


def test_transition_budget_is_kept_inside_the_kernel():
    system, x0, _ = make_oscillator_example("ex2")
    fast, slow = both_paths(system, x0, "free", 4.0, 1e-2, 1e-5, "rk4", max_transitions=37, continuation=False)
    assert fast.status == "max_transitions" and len(fast.transitions) == 37
    assert_same_execution(fast, slow)


def test_run_ending_inside_a_strip_after_kernel_transitions():
    # A wide strip (5 cm) holds the ball for ~eps - tau seconds; end the run inside the third hold.
    system = make_bouncing_ball(9.81, 0.8)
    probe = simulate(system, [1.0, 0.0], "flight", 3.0, 1e-2, 0.05, "rk4")
    third = probe.transitions[2]
    t_end = 0.5 * (third.time + third.exit_time)
    fast, slow = both_paths(system, [1.0, 0.0], "flight", t_end, 1e-2, 0.05, "rk4")
    assert fast.final_in_strip and fast.status == "finished" and len(fast.transitions) == 2
    assert_same_execution(fast, slow)


def test_reset_into_a_strip_goes_back_to_python_at_the_entry():
    # The reset puts x0 inside the strip (guard 0.5 - x0, image x0 = 0.5 + eps/2): every entry
    # crosses at once (zero-time transitions) until the budget, as on the Python path.
    eps = 1e-3
    system = probe_system([0.0, 1.0, 0.0, 0.0, 0.5, 0.5 + 0.5 * eps])
    fast, slow = both_paths(system, [0.0, 1.0], "m", 2.0, 1e-2, eps, "rk4", max_transitions=5)
    assert fast.status == "max_transitions"
    assert_same_execution(fast, slow)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_non_finite_reset_image_ends_both_paths_alike():
    system = probe_system([0.0, 1.0, 0.0, 0.0, 0.5, math.nan])
    fast, slow = both_paths(system, [0.0, 1.0], "m", 2.0, 1e-2, 1e-3, "rk4")
    assert fast.status == "non_finite" and "reset of transition wrap" in fast.message
    assert_same_execution(fast, slow)


def test_plan_reproduces_every_tableau():
    # The grouped arrays must encode exactly A's rows and b: rebuild them from the plan.
    for tableau in METHODS.values():
        plan = plan_for(tableau)
        s = tableau.stages
        for row in range(1, s + 1):
            weights = np.zeros(s)
            for g in range(plan.n_groups[row]):
                for m in plan.members[row, g, : plan.n_members[row, g]]:
                    weights[m] += plan.weights[row, g]
            expected = tableau.b if row == s else tableau.A[row]
            assert np.array_equal(weights, expected), (tableau.name, row)


def test_closures_are_not_importable_and_module_functions_are():
    assert importable(probe_field) == f"{probe_field.py_func.__module__}:probe_field"

    def make():
        @numba.njit
        def inner(t, x, p):
            return x

        return inner

    assert importable(make()) is None


@pytest.mark.slow
def test_closure_twin_runs_compiled_in_memory():
    # A twin defined in a function cannot be imported by a generated module: its kernel is
    # compiled in this process only (several seconds), and must still match the Python path.
    g = 9.81

    @numba.njit
    def field(t, x, p):
        out = np.empty(2)
        out[0] = x[1]
        out[1] = -g
        return out

    @numba.njit
    def guards(x, p):
        out = np.empty(1)
        out[0] = x[0] if x[0] > x[1] else x[1]
        return out

    twin = CompiledMode(field, guards, 1)
    system = HybridSystem(
        {"f": Mode(2, lambda t, x, u: np.array([x[1], -g]), compiled=twin)},
        [Transition("f", "f", lambda x: x[0] if x[0] > x[1] else x[1], lambda x: np.array([x[0], -0.5 * x[1]]))],
    )
    fast, slow = both_paths(system, [1.0, 0.0], "f", 1.5, 1e-2, 1e-4, "rk4", max_transitions=100)
    assert_same_execution(fast, slow)


def test_the_kernel_compiles_the_python_loops_own_rules():
    # One semantics: the generated kernel holds the decision rules the Python loop calls, copied
    # from their source (crossing search, step-size update, landing aim, strip exit, error norm).
    import inspect

    from legsim.compiled import kernel
    from legsim.compiled.generate import kernel_source
    from legsim.methods.stepper import error_scale, scaled_norm
    from legsim.relaxed import rules

    source = kernel_source([], cache=False)
    for rule in (
        rules.crossing_start,
        rules.crossing_point,
        rules.crossing_update,
        rules.rejected_step,
        rules.proposed_step,
        rules.kept_proposal,
        rules.aimed_step,
        rules.strip_exit_time,
        error_scale,
        scaled_norm,
    ):
        assert inspect.getsource(rule).rstrip() in source, rule.__name__
        assert rule in kernel.RULES
    for constant in ("STALL", "MIN_STEP", "SAFETY", "MAX_FACTOR"):
        assert f"{constant} = {getattr(rules, constant)!r}" in source


def test_dop853_blended_error_norm_same_on_both_paths():
    # DOP853's tableau (stacked stages, Hairer's blended E5/E3 norm) in the kernel. The Python
    # stepper sums its long rows by a matrix product, the kernel term by term; the error estimate
    # is a small difference of large stage sums, so rounding moves it by up to ~1e-4 relative and
    # the step sizes by ~1e-8 s. Not bit for bit, then, but the same run: the same steps,
    # rejections and evaluations, transitions at the same times, the same final state.

    system, x0, _ = make_oscillator_example("ex1")
    fast, slow = both_paths(
        system, x0, "free", 12.0, 0.5, 1e-6, get_method("dop853"), landing="aim", rtol=1e-10, atol=1e-10
    )
    assert fast.status == slow.status == "finished"
    assert len(fast.transitions) == 4 and fast.counters["error_rejections"] > 0
    for key in ("steps", "halvings", "error_rejections", "field_evals", "transitions"):
        assert fast.counters[key] == slow.counters[key], key
    assert abs(fast.counters["guard_evals"] - slow.counters["guard_evals"]) <= 0.02 * slow.counters["guard_evals"]
    for a, b in zip(fast.transitions, slow.transitions, strict=True):
        assert abs(a.time - b.time) < 1e-12
    np.testing.assert_allclose(fast.segments[-1].x[-1], slow.segments[-1].x[-1], rtol=0, atol=1e-10)
