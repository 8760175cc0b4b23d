"""Distances between executions: a relaxed simulation of the bouncing ball against its exact
execution (written here), where everything is known in closed form.

Free fall is a quadratic in t, so RK4 and the Hermite crossing are exact: the simulation
crosses the ground at exactly t1 = sqrt(2 z0 / g), holds q = (0, -v1) in the strip until its
exit time, then restarts from R(q) = (0, c v1). After the exit it is the exact execution
delayed by the lag L = exit_time - t1: x_sim(t) = x_ref(t - L). Inside the strip the state is
the strip point (q, tau(t)) with tau from 0 at the crossing to the landing depth at the landing
time and then at unit rate to eps at the exit (paper 000 Fig. 12, step 12).

Bad executions (no sample method, samples that do not fit the system or the times, positions
that are not numbers) raise with a message naming the argument: the last tests.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from helpers.metric_systems import C, ball, two_mode
from legsim import load_execution, save_execution, simulate
from legsim.errors import LegsimError
from legsim.execution import Samples
from legsim.metric import MetricError, distance, distances, position_error, rho, trajectory_space_distance

G, Z0 = 9.81, 1.0
T1 = math.sqrt(2 * Z0 / G)
V1 = G * T1


class BallReference:
    """Exact execution from (Z0, 0) until just before the second impact."""

    t_end = T1 + 2 * C * V1 / G

    def state(self, t: float) -> np.ndarray:
        if t < T1:
            return np.array([Z0 - G * t * t / 2, -G * t])
        s = t - T1
        return np.array([C * V1 * s - G * s * s / 2, C * V1 - G * s])

    def sample(self, times) -> Samples:
        times = np.atleast_1d(np.asarray(times, dtype=float))
        return Samples(times, ["fall"] * len(times), [self.state(t) for t in times], np.zeros(len(times), bool))


@pytest.fixture(scope="module", params=[(1e-3, 1e-2), (3.7e-3, 1e-3), (1e-2, 2e-2)])
def run(request):
    h, eps = request.param
    system = ball()
    ex = simulate(system, [Z0, 0.0], "fall", 0.9 * BallReference.t_end, h, eps)
    assert ex.status == "finished" and len(ex.transitions) == 1
    return system, ex, eps


def test_after_the_strip_the_distance_is_that_of_the_lagged_exact_execution(run):
    system, ex, eps = run
    ref = BallReference()
    tr = ex.transitions[0]
    assert tr.time == pytest.approx(T1, abs=1e-12)
    lag = tr.exit_time - T1
    times = np.linspace(tr.exit_time + 1e-6, ex.t_end, 200)
    lagged = np.array([np.linalg.norm(ref.state(t - lag) - ref.state(t)) for t in times])
    np.testing.assert_allclose(distances(system, ex, ref, times, eps), lagged, rtol=1e-9, atol=1e-12)
    # The lag is the strip time: at most eps plus the time spent past the guard by the step.
    assert 0.0 <= lag <= eps + (tr.landing_time - tr.time)


def test_inside_the_strip_the_state_has_the_transverse_coordinate_of_fig_12(run):
    system, ex, eps = run
    ref = BallReference()
    tr = ex.transitions[0]
    q = tr.state_before
    times = np.linspace(tr.time, tr.exit_time, 41)[1:-1]
    samples = ex.sample(times)
    assert samples.in_strip.all()
    for t, d in zip(times, distances(system, ex, ref, times, eps), strict=True):
        if t <= tr.landing_time:
            tau = tr.depth * (t - tr.time) / (tr.landing_time - tr.time)
        else:
            tau = tr.depth + (t - tr.landing_time)
        y = ref.state(t)  # after the impact: on the reset side
        via_guard = tau + distance(system, ("fall", q), ("fall", y), eps)
        via_reset = (eps - tau) + np.linalg.norm(np.array([q[0], -C * q[1]]) - y)
        assert d == pytest.approx(min(via_guard, via_reset), abs=1e-12)


def test_rho_is_the_largest_sampled_distance_and_zero_against_itself(run, tmp_path):
    system, ex, eps = run
    ref = BallReference()
    times = np.linspace(0.0, ex.t_end, 301)
    assert rho(system, ex, ref, times, eps) == pytest.approx(distances(system, ex, ref, times, eps).max(), abs=0)
    path = save_execution(ex, tmp_path / "ball.npz")
    assert rho(system, ex, load_execution(path), times, eps) == 0.0


def test_relaxation_error_is_order_eps(run):
    # The lagged execution moves at most max |f| = sqrt(v^2 + g^2) per unit time, and the
    # crossing itself is exact: rho <= (lag) * max |f| + eps.
    system, ex, eps = run
    ref = BallReference()
    lag = ex.transitions[0].exit_time - T1
    times = np.linspace(0.0, ex.t_end, 401)
    bound = lag * math.hypot(V1, G) + eps
    assert rho(system, ex, ref, times, eps) <= bound


def test_position_error_of_eq_30_for_positions_only():
    ref = BallReference()
    times = np.linspace(0.0, 0.8, 81)
    exact = np.array([ref.state(t)[0] for t in times])
    noisy = exact + 1e-3 * np.sin(7 * times)
    expected = float(np.max(np.abs(1e-3 * np.sin(7 * times))))
    assert position_error(noisy, ref, times) == pytest.approx(expected, abs=1e-15)
    assert position_error(noisy, lambda t: np.array([ref.state(s)[0] for s in t]), times) == pytest.approx(
        expected, abs=1e-15
    )
    ex = simulate(ball(), [Z0, 0.0], "fall", 0.8, 1e-3, 1e-3)
    by_name = position_error(ex, ref, times, coordinate="z")
    by_index = position_error(ex, ref, times, coordinate=0)
    assert (
        by_name == by_index == pytest.approx(max(abs(ex.state_at(t)[1][0] - ref.state(t)[0]) for t in times), abs=1e-15)
    )


def test_trajectory_space_distance_is_the_euclidean_sup_within_one_mode():
    ex_a = simulate(ball(), [Z0, 0.0], "fall", 0.8, 1e-3, 1e-3)
    ex_b = simulate(ball(), [Z0 + 0.01, 0.0], "fall", 0.8, 1e-3, 1e-3)
    times = np.linspace(0.0, 0.8, 101)
    expected = max(np.linalg.norm(ex_a.state_at(t)[1] - ex_b.state_at(t)[1]) for t in times)
    assert trajectory_space_distance(ex_a, ex_b, times) == pytest.approx(expected, abs=1e-15)


# -- bad executions: the error class and its message ---------------------------------------------
def test_times_outside_an_execution_name_its_interval(execution):
    with pytest.raises(LegsimError, match=r"sample times must lie in \[0.0, 0.5\]"):
        rho(ball(), execution, execution, [0.1, 0.7], 1e-3)


def test_an_execution_needs_a_sample_method(execution):
    with pytest.raises(MetricError, match=r"execution_b must have a sample\(times\) -> Samples method .* got list"):
        distances(ball(), execution, [1, 2], [0.1], 1e-3)


def test_samples_must_match_the_system(execution):
    with pytest.raises(MetricError, match=r"execution_a at t=0.1: unknown mode 'fall' of two-mode"):
        rho(two_mode(), execution, execution, [0.1], 1e-3)


def test_samples_must_have_one_state_per_time(execution):
    class Short:
        def sample(self, times):
            return execution.sample(times[:1])

    with pytest.raises(MetricError, match=r"execution_b.sample\(times\) must return Samples with one mode and state"):
        rho(ball(), execution, Short(), [0.1, 0.2], 1e-3)


@pytest.mark.parametrize(
    "simulated, coordinate, message",
    [
        ([1.0, 2.0, 3.0], 0, "simulated gives 3 positions for 2 times"),
        ([1.0, math.inf], 0, "simulated positions must be finite"),
        (["x", "y"], 0, "simulated positions must be numbers"),
        ("execution", "height", r"simulated: no coordinate named 'height' in mode 'fall' \(names: \('z', 'zd'\)\)"),
        ("execution", 2, r"simulated: coordinate 2 is not an index of the 2-d state in mode 'fall'"),
    ],
)
def test_bad_position_error_input(execution, simulated, coordinate, message):
    if simulated == "execution":
        simulated = execution
    with pytest.raises(MetricError, match=message):
        position_error(simulated, execution, [0.1, 0.2], coordinate=coordinate)
