"""Landing rules: halving, aiming at the strip's middle on the failed step's interpolant, and
landing on the step's own dense output (no step retried); trial steps that leave the model's
range are shortened like steps past a strip; the short first step to a simultaneous strip."""

import math

import numpy as np
import pytest

from legsim import HybridSystem, Mode, Transition, simulate
from legsim.errors import ModelBreakdown, SimulationError
from legsim.methods import get_method


def doubling_system() -> HybridSystem:
    """x' = x, reset at x = 2 back to 1: the crossings are at k ln 2 (plus the strips' delays)."""
    return HybridSystem(
        {"grow": Mode(1, lambda t, x, u: x.copy(), names=("x",))},
        [Transition("grow", "grow", guard=lambda x: 2.0 - x[0], reset=lambda x: x * 0.5, name="halve")],
    )


@pytest.mark.parametrize("method", ["dopri5", "bs32"])
def test_dense_landing_finds_the_crossing_without_retrying_a_step(method):
    eps, tol = 1e-9, 1e-10
    runs = {
        landing: simulate(
            doubling_system(), [1.0], "grow", 3.0, 0.5, eps, method=method, rtol=tol, atol=tol, landing=landing
        )
        for landing in ("aim", "dense")
    }
    dense, aim = runs["dense"], runs["aim"]
    assert dense.status == aim.status == "finished"
    assert len(dense.transitions) == len(aim.transitions) == 4
    for k, tr in enumerate(dense.transitions):
        # q on the guard to the crossing search's tolerance; the k-th crossing at (k+1) ln 2 plus
        # the k earlier strips' delays (each eps - tau <= eps).
        assert tr.state_before[0] == pytest.approx(2.0, abs=1e-11)
        assert 0.0 <= tr.depth <= eps
        assert (k + 1) * math.log(2.0) - 1e-9 <= tr.time <= (k + 1) * math.log(2.0) + k * eps + 1e-9
    # Every landing shortened exactly one step and retried none: fewer field evaluations.
    assert dense.counters["halvings"] == len(dense.transitions)
    assert dense.counters["field_evals"] < aim.counters["field_evals"]


def test_dense_landing_with_dop853_keeps_the_strip_guarantee_on_the_pronk():
    from legsim.bench.cases import make_case
    from legsim.bench.work_precision import own_points, position_error

    case = make_case("pronk")  # its reference: solve_ivp DOP853 at rtol = atol = 1e-12
    eps = 1e-9
    runs = {
        landing: simulate(
            case.system,
            case.x0,
            case.mode,
            2.0,
            0.1,
            eps,
            method=get_method("dop853"),
            rtol=1e-8,
            atol=1e-8,
            landing=landing,
        )
        for landing in ("aim", "dense")
    }
    ex, aim = runs["dense"], runs["aim"]
    assert ex.status == "finished" and len(ex.transitions) == 8
    assert all(0.0 <= tr.depth <= eps for tr in ex.transitions)
    errors = {k: position_error(*own_points(r, case.positions), case.reference_positions) for k, r in runs.items()}
    # q on the seventh-order interpolant instead of a retried step and its cubic Hermite: as
    # accurate (measured 7.0e-7 against 7.1e-7 m; the level is the tolerance's), with fewer field
    # evaluations.
    assert errors["dense"] <= 1.1 * errors["aim"] and errors["dense"] < 1e-6
    assert ex.counters["field_evals"] < aim.counters["field_evals"]

    # The same transitions, to the runs' accuracy (the symmetric pronk's legs touch down together,
    # in either order within the strip).
    def by_name(run):
        out = {}
        for tr in run.transitions:
            out.setdefault(tr.name, []).append(tr.time)
        return out

    ours, theirs = by_name(ex), by_name(aim)
    assert sorted(ours) == sorted(theirs)
    for name in ours:
        np.testing.assert_allclose(ours[name], theirs[name], rtol=0, atol=1e-7)


def test_dense_landing_needs_a_method_with_a_continuous_extension():
    with pytest.raises(SimulationError, match=r"landing 'dense'.*'rk4'.*aim"):
        simulate(doubling_system(), [1.0], "grow", 1.0, 0.1, 1e-6, method="rk4", landing="dense")
    with pytest.raises(SimulationError, match="landing must be one of"):
        simulate(doubling_system(), [1.0], "grow", 1.0, 0.1, 1e-6, landing="bisect")


def ball_through_the_floor(breakdown_depth: float) -> HybridSystem:
    """A bouncing ball (c = 0.5) whose model is undefined deeper than breakdown_depth below the
    floor (think of a runner's hip through the ground): the guard raises ModelBreakdown there."""

    def floor(x):  # "at the floor moving down", so that a bounce's image is inside the domain
        if x[0] < -breakdown_depth:
            raise ModelBreakdown(f"ball {-x[0]:.3g} m below the floor")
        return max(x[0], x[1])

    return HybridSystem(
        {"fly": Mode(2, lambda t, x, u: np.array([x[1], -9.81]), names=("z", "zd"))},
        [Transition("fly", "fly", guard=floor, reset=lambda x: np.array([x[0], -0.5 * x[1]]), name="bounce")],
    )


@pytest.mark.parametrize("landing", ["halve", "aim", "dense"])
def test_a_trial_step_that_leaves_the_models_range_is_shortened(landing):
    # From 1 m at rest, a 1 s trial step ends 3.9 m below the floor, past the model's range: it
    # is halved like a step past a strip, not the end of the run. RK4 and
    # dopri5 are exact on parabolas, so the impacts are the closed form's.
    method = "dopri5" if landing == "dense" else "rk4"
    eps = 1e-9
    # (t_final = 1 s: before the third impact, far from the Zeno time 1.355 s.)
    ex = simulate(ball_through_the_floor(0.3), [1.0, 0.0], "fly", 1.0, 1.0, eps, method=method, landing=landing)
    assert ex.status == "finished", ex.message
    t1 = math.sqrt(2.0 / 9.81)
    v1 = 9.81 * t1
    t2 = t1 + 2 * 0.5 * v1 / 9.81
    times = [tr.time for tr in ex.transitions]
    assert len(times) == 2
    assert times[0] == pytest.approx(t1, abs=1e-9)
    assert times[1] == pytest.approx(t2, abs=1e-8)


def test_a_flow_into_the_models_range_ends_with_model_breakdown():
    # Falling without a floor: the flow itself reaches the model's boundary at t = 1.1 s. Halving
    # cannot get past it; the run ends once the boundary is within 2^-10 of a step (instead of
    # creeping towards it by ever shorter steps), naming the mode.
    system = HybridSystem(
        {"fall": Mode(1, lambda t, x, u: np.array([-1.0]), names=("z",))},
        [
            Transition(
                "fall", "fall", guard=lambda x: _raise_below(x[0], 0.0) + 10.0, reset=lambda x: x.copy(), name="never"
            )
        ],
    )
    h = 0.25
    ex = simulate(system, [1.1], "fall", 3.0, h, 1e-6, method="rk4")
    assert ex.status == "model_breakdown"
    assert "mode 'fall'" in ex.message and "leaves the model's range" in ex.message
    assert 1.1 - h / 2**10 <= ex.t_end <= 1.1
    assert ex.counters["steps"] < 40


def _raise_below(z: float, depth: float) -> float:
    if z < depth:
        raise ModelBreakdown(f"z = {z:.3g} is below {depth}")
    return z


def test_a_tolerance_means_what_it_means_for_solve_ivp_on_the_pronk():
    # Each new mode starts at the standard starting step, as solve_ivp restarts after an event,
    # and DOP853 is controlled as scipy controls it: at rtol = atol = 1e-6 (largest step 0.2 s)
    # the relaxed run is as accurate as solve_ivp's DOP853 with events (9.6e-6 m both; carrying
    # the step over each transition would not be).
    from legsim.baselines import simulate_events
    from legsim.bench.cases import make_case
    from legsim.bench.work_precision import own_points, position_error

    case = make_case("pronk")
    relaxed = simulate(
        case.system,
        case.x0,
        case.mode,
        2.0,
        0.2,
        1e-9,
        method=get_method("dop853"),
        rtol=1e-6,
        atol=1e-6,
        landing="dense",
    )
    ivp = simulate_events(case.ivp_system, case.x0, case.mode, 2.0, method="DOP853", rtol=1e-6, atol=1e-6, max_step=0.2)
    errors = [position_error(*own_points(r, case.positions), case.reference_positions) for r in (relaxed, ivp)]
    assert relaxed.status == ivp.status == "finished" and len(relaxed.transitions) == len(ivp.transitions) == 8
    assert errors[0] <= 1.2 * errors[1], errors


def drift(gap: float, calls: dict | None = None) -> HybridSystem:
    """x' = y' = 1: mode a leaves at x = 1, mode b at y = 1 + gap, mode c runs free; gap = 0 is
    a simultaneous event. ``calls`` counts the field evaluations per mode."""
    calls = {} if calls is None else calls

    def field_of(mode):
        def field(t, x, u):
            calls[mode] = calls.get(mode, 0) + 1
            return np.ones(2)

        return field

    def identity(x):
        return x.copy()

    names = ("x", "y")
    return HybridSystem(
        {m: Mode(2, field_of(m), names=names) for m in ("a", "b", "c")},
        [
            Transition("a", "b", guard=lambda x: 1.0 - x[0], reset=identity, name="a_to_b"),
            Transition("b", "c", guard=lambda x: 1.0 + gap - x[1], reset=identity, name="b_to_c"),
        ],
    )


def test_a_simultaneous_event_costs_a_short_step_and_stays_continuous():
    # Entering b on b's guard (gap 0) or a hair before it (gap 1e-13, 1e-11): the first step in b
    # only has to reach b's strip, so it is a Heun step of about eps / 2 (one field evaluation),
    # not a full dopri5 step (six). The crossing of b_to_c is the exact one (linear flow), and
    # the execution is continuous in the gap: the symmetric case is the limit of its neighbours.
    eps, h, tol = 1e-9, 0.25, 1e-10
    runs, calls = {}, {}
    for gap in (0.0, 1e-13, 1e-11):
        calls[gap] = {}
        runs[gap] = simulate(
            drift(gap, calls[gap]), [0.0, 0.0], "a", 2.0, h, eps, method="dopri5", rtol=tol, atol=tol, landing="dense"
        )
    for gap, ex in runs.items():
        assert ex.status == "finished" and ex.mode_sequence == ["a", "b", "c"]
        a_to_b, b_to_c = ex.transitions
        # b is entered at a_to_b's exit, still at (1, 1); y then has 1 + gap - 1 to go
        assert b_to_c.time == pytest.approx(a_to_b.exit_time + gap, abs=1e-15)
        np.testing.assert_allclose(b_to_c.state_before, [1.0 + gap, 1.0 + gap], rtol=0, atol=1e-15)
        assert 0.0 <= b_to_c.depth <= eps
        # Mode b: its entry evaluation, the starting-step estimate and the short step (a full
        # dopri5 step would make it 8).
        assert calls[gap]["b"] == 3, calls[gap]
    # Continuity: the gap moves the final state by the gap (the strips' holds by less than eps).
    final = {gap: ex.final_state for gap, ex in runs.items()}
    for gap in (1e-13, 1e-11):
        assert np.abs(final[gap] - final[0.0]).max() <= gap + 1e-12


def test_a_mode_entered_on_a_guard_by_rounding_crosses_it_by_a_short_step():
    # b is entered 1e-13 past b's guard, within the band that counts as on the guard
    # (rules.on_guard_depth): the second foot of a symmetric touchdown, behind the first by
    # rounding. As a hair before the guard, the first step in b is the short Heun step to the
    # strip's middle (three evaluations in b; a full dopri5 step would make it eight), and the
    # crossing is at b's entry, where the guard is already past.
    eps, h, tol, gap = 1e-9, 0.25, 1e-10, -1e-13
    runs, calls = {}, {gap: {}, 0.0: {}}
    for g in (gap, 0.0):
        runs[g] = simulate(
            drift(g, calls[g]), [0.0, 0.0], "a", 2.0, h, eps, method="dopri5", rtol=tol, atol=tol, landing="dense"
        )
    ex = runs[gap]
    assert ex.status == "finished" and ex.mode_sequence == ["a", "b", "c"]
    a_to_b, b_to_c = ex.transitions
    assert b_to_c.time == a_to_b.exit_time
    np.testing.assert_array_equal(b_to_c.state_before, a_to_b.state_after)
    assert calls[gap]["b"] == 3, calls[gap]
    # Continuous with the symmetric case: the final states differ by the gap, to rounding.
    assert np.abs(ex.final_state - runs[0.0].final_state).max() <= abs(gap) + 1e-12


def test_dense_landing_aims_at_the_strips_middle_through_a_kinked_guard():
    # Example 2's mass sticks on the stop: its guard max(x_max - x, -xd) has a kink there, the
    # secant from q to the step's end lands at the strip's very edge (depth ~1e-12 of eps = 1e-7),
    # each crossing then holds the state for ~1e-6 s instead of ~2e-4 s and the chatter took
    # 1e6 transitions for 3 ms of sticking. Landing in the strip's middle half keeps dense
    # landing's transition count with the aimed retry's. (The plain relaxed semantics: with its
    # continuation the mass would stick instead.)
    from legsim.bench.overhead import example

    system, law, x0, _ = example("ex2")
    eps = 1e-7
    runs = {
        landing: simulate(
            system,
            x0,
            "free",
            0.5,
            0.1,
            eps,
            method="dopri5",
            control=law,
            rtol=1e-8,
            atol=1e-8,
            landing=landing,
            max_transitions=20_000,
            continuation=False,
        )
        for landing in ("aim", "dense")
    }
    assert runs["aim"].status == runs["dense"].status == "finished"
    n_aim, n_dense = len(runs["aim"].transitions), len(runs["dense"].transitions)
    assert n_aim > 100  # the mass chatters on the stop
    assert n_dense <= 1.1 * n_aim
    depths = np.array([tr.depth for tr in runs["dense"].transitions])
    assert np.all((depths >= 0.25 * eps) & (depths <= 0.75 * eps))


def two_planes() -> HybridSystem:
    """(p, y)' = (-1, -1): A -> B at p = 10, B -> C at y = 10 (identity resets)."""

    def field(t, x, u):
        return np.array([-1.0, -1.0])

    names = ("p", "y")
    return HybridSystem(
        {m: Mode(2, field, names=names) for m in ("A", "B", "C")},
        [
            Transition("A", "B", guard=lambda x: x[0] - 10.0, reset=lambda x: x.copy(), name="AB"),
            Transition("B", "C", guard=lambda x: x[1] - 10.0, reset=lambda x: x.copy(), name="BC"),
        ],
    )


def test_the_short_first_step_never_passes_t_final():
    # B is entered 3e-7 s before BC's guard; t_final falls inside the short step's reach. The run
    # ends at t_final in B, with no strip or point after it: the short step never lands past it.
    eps = 1e-6
    t_final = 1.05 + 1e-6 + 1e-7
    ex = simulate(
        two_planes(),
        [11.05, 11.05 + 0.3 * eps],
        "A",
        t_final,
        0.1,
        eps,
        method="dopri5",
        rtol=1e-6,
        atol=1e-9,
        landing="dense",
    )
    assert ex.status == "finished" and ex.t_end == t_final
    assert max(seg.t[-1] for seg in ex.segments) <= t_final
    assert all(s.time <= t_final and s.exit_time <= t_final for s in ex.strips)
    assert 0.0 <= ex.counters["strip_time"] <= eps + 1e-15


@pytest.mark.parametrize("landing", ["halve", "dense"])
def test_a_reset_leaving_the_models_range_ends_the_run_once(landing):
    # The reset raises ModelBreakdown at the first crossing (x = 2 at t = ln 2): the run ends there
    # with model_breakdown, its one segment stored once and its steps counted once.
    def reset(x):
        if x[0] > 1.5:
            raise ModelBreakdown("reset out of range")
        return 0.5 * x

    system = HybridSystem(
        {"grow": Mode(1, lambda t, x, u: x.copy(), names=("x",))},
        [Transition("grow", "grow", guard=lambda x: 2.0 - x[0], reset=reset, name="halve")],
    )
    ex = simulate(system, [1.0], "grow", 2.0, 0.1, 1e-6, method="dopri5", rtol=1e-6, atol=1e-9, landing=landing)
    assert ex.status == "model_breakdown" and "reset out of range" in ex.message and "halve" in ex.message
    assert len(ex.segments) == 1
    assert ex.t_end == pytest.approx(math.log(2.0), abs=1e-6)
    assert ex.counters["steps"] == len(ex.segments[0].t) - 1  # the landing step ends at q


def test_dense_landing_reports_a_nan_guard_like_any_step():
    # A second guard is nan inside the first guard's strip: the landing point is not accepted
    # (min() would skip a nan that is not first); the run ends non_finite naming that guard.
    eps = 1e-6

    def g2(x):
        return math.nan if 10 - 0.8 * eps < x[0] < 10 - 0.2 * eps else 1.0

    field = lambda t, x, u: np.array([-1.0])  # noqa: E731
    system = HybridSystem(
        {"A": Mode(1, field, names=("p",)), "B": Mode(1, field, names=("p",))},
        [
            Transition("A", "B", guard=lambda x: x[0] - 10.0, reset=lambda x: x.copy(), name="AB"),
            Transition("A", "B", guard=g2, reset=lambda x: x.copy(), name="nanguard"),
        ],
    )
    ex = simulate(system, [11.05], "A", 1.5, 0.1, eps, method="dopri5", rtol=1e-6, atol=1e-9, landing="dense")
    assert ex.status == "non_finite" and "nanguard" in ex.message


@pytest.mark.parametrize("method", ["dopri5", "dop853"])
def test_aimed_landing_in_a_thin_strip_costs_about_one_trial_step(method):
    # The pronk with eps = 1e-9 m: its liftoffs happen where the cubic interpolant of a 0.04 s
    # step is ~3e-6 m off, so the first aim misses the strip; the second aim, on the shorter
    # failed step, finds the crossing at s ~ 0.99997 where the interpolant is exact to far below
    # eps, so the aim is kept however close to the step's end it falls.
    from legsim.robots import pronk

    model = pronk.make()
    ex = simulate(
        model.system,
        pronk.state(),
        model.initial_mode,
        2.0,
        0.1,
        1e-9,
        method=method,
        rtol=1e-8,
        atol=1e-8,
        landing="aim",
    )
    assert ex.status == "finished" and len(ex.transitions) == 8
    assert ex.counters["halvings"] / len(ex.transitions) <= 1.5
