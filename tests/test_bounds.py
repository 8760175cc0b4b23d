"""Global error bounds of paper 004 Section III (legsim.bounds)."""

import itertools
import math

import numpy as np
import pytest
import scipy.linalg as sl
from scipy.stats import norm

from legsim import HybridSystem, Mode, SimulationError, simulate
from legsim.bounds import (
    LocalErrorEstimator,
    ModeFlow,
    accumulate_bound,
    ball_fraction_past,
    error_bound,
    field_jacobian,
    lipschitz_estimate,
)
from legsim.systems.circular_flow import CircularReference
from legsim.systems.circular_flow import make_system as circular_flow

# A non-normal stable matrix (its sigma_max exceeds its spectral radius) and a rotation.
A_NONNORMAL = np.array([[-0.5, 2.0], [-1.0, -0.2]])
A_ROTATION = np.array([[0.0, 1.0], [-1.0, 0.0]])
X0 = np.array([1.0, 0.5])


def linear(A, jacobian=False):
    return HybridSystem({"m": Mode(len(A), lambda t, x, u: A @ x, jacobian=(lambda t, x, u: A) if jacobian else None)})


def exact(A, t):
    """x(t) = e^{A t} X0 through the eigendecomposition (both matrices are diagonalisable),
    checked against scipy's expm at one time."""
    lam, V = np.linalg.eig(A)
    c = np.linalg.solve(V, X0)
    x = np.real((V[None, :, :] * (np.exp(np.outer(t, lam)) * c)[:, None, :]).sum(axis=2))
    assert np.allclose(x[-1], sl.expm(A * t[-1]) @ X0, atol=1e-12)
    return x


def true_errors(A, seg):
    return np.linalg.norm(exact(A, seg.t) - seg.x, axis=1)


# Slopes of the bound in h: the order of what is estimated (rk4 against dopri5: the rk4 error;
# bs32 and dopri5 alone: their embedded lower-order member), minus one for the accumulation.
@pytest.mark.parametrize("method, slope", [("euler", 1), ("rk4", 4), ("bs32", 2), ("dopri5", 4)])
@pytest.mark.parametrize("A", [A_NONNORMAL, A_ROTATION], ids=["nonnormal", "rotation"])
def test_bound_contains_true_error_and_vanishes_at_the_method_rate(method, slope, A):
    hs = [0.1, 0.05, 0.025]
    maxima = []
    for h in hs:
        system = linear(A)
        ex = simulate(system, X0, "m", 4.0, h, 1e-3, method=method)
        eb = error_bound(ex, system)
        seg = eb.segments[0]
        err = true_errors(A, seg)
        assert np.all(seg.bound >= err), (method, h, (seg.bound - err).min())
        maxima.append(seg.bound.max())
    fitted = np.polyfit(np.log(hs), np.log(maxima), 1)[0]
    assert abs(fitted - slope) < 0.3, fitted


def test_lipschitz_is_sigma_max_of_the_jacobian_with_and_without_a_given_jacobian():
    for given in (False, True):
        system = linear(A_NONNORMAL, jacobian=given)
        mode = system.mode("m")
        J = field_jacobian(mode, 0.0, X0)
        assert np.allclose(J, A_NONNORMAL, atol=1e-9)
        assert lipschitz_estimate(mode, 0.0, X0) == pytest.approx(np.linalg.svd(A_NONNORMAL)[1][0], rel=1e-9)
    ex = simulate(linear(A_NONNORMAL), X0, "m", 1.0, 0.1, 1e-3)
    eb = error_bound(ex, linear(A_NONNORMAL))
    assert eb.segments[0].lipschitz == pytest.approx(np.linalg.svd(A_NONNORMAL)[1][0], rel=1e-9)


def test_accumulation_matches_the_paper_sum():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.01, 0.1, 30))
    le = rng.uniform(0, 1e-3, 30)
    L = 1.7
    expected = [le[n] + sum(le[i] * math.exp(L * (t[n] - t[i])) for i in range(n)) for n in range(30)]
    assert np.allclose(accumulate_bound(t, le, L), expected, rtol=1e-12)
    # An initial uncertainty is carried as b0 e^{L (t - t0)}.
    assert np.allclose(accumulate_bound(t, np.zeros(30), L, b0=2.0), 2.0 * np.exp(L * (t - t[0])))


def test_hybrid_execution_bound_contains_each_visit_error_including_the_strip_point():
    # Circle of radius 1.5 crossing x1 = 1 twice: each visit is its own IVP from the visit's
    # first point, and its last point is the interpolated crossing point.
    system = circular_flow()
    ref = CircularReference(1.0, 1.0)
    ex = simulate(system, [0.0, 1.5], "inside", 3.0, 0.1, 1e-4, method="rk4")
    assert len(ex.transitions) == 2
    eb = error_bound(ex, system)
    for seg in eb.segments:
        exact = ref.state(seg.x[0], seg.t, t0=seg.t[0])
        err = np.linalg.norm(exact - seg.x, axis=1)
        assert np.all(seg.bound >= err)
        assert seg.lipschitz == pytest.approx(1.0)


@pytest.mark.parametrize(
    "dim, closed_form",
    [
        (1, lambda u: (1 - u) / 2),
        # Circular segment: (arccos u - u sqrt(1 - u^2)) / pi.
        (2, lambda u: (np.arccos(u) - u * np.sqrt(1 - u * u)) / np.pi),
        # Spherical cap: (1 - u)^2 (2 + u) / 4.
        (3, lambda u: (1 - u) ** 2 * (2 + u) / 4),
    ],
)
def test_ball_fraction_past_a_hyperplane_matches_closed_forms(dim, closed_form):
    u = np.linspace(-0.99, 0.99, 41)
    got = ball_fraction_past(u * 2.0, 2.0, dim)
    assert np.allclose(got, closed_form(u), atol=1e-13)
    assert ball_fraction_past(0.0, 1.0, dim) == pytest.approx(0.5)
    assert ball_fraction_past(3.0, 1.0, dim) == 0.0 and ball_fraction_past(-3.0, 1.0, dim) == 1.0
    # A zero radius is a point: inside (g >= 0) or past.
    assert ball_fraction_past(0.0, 0.0, dim) == 0.0 and ball_fraction_past(-1e-12, 0.0, dim) == 1.0


def test_high_dimensional_ball_concentrates_at_its_equator():
    # Volume concentrates near any hyperplane through the centre as dim grows, so a fixed
    # relative offset leaves less and less of the ball past the plane.
    fractions = [float(ball_fraction_past(0.2, 1.0, d)) for d in (2, 10, 50, 200)]
    assert all(a > b for a, b in itertools.pairwise(fractions))
    # A coordinate of a uniform point of the d-ball tends to N(0, 1/(d + 2)): the cap beyond
    # 0.2 tends to the normal tail at 0.2 sqrt(d + 2) (2.8 sigma at d = 200; 10% at that size).
    assert fractions[-1] == pytest.approx(norm.sf(0.2 * math.sqrt(202)), rel=0.1)


def test_mode_flow_ball_contains_the_exact_solution_between_points():
    # The flow's ball must cover the Hermite-interpolated trajectory, not only its points.
    system = circular_flow()
    ref = CircularReference(1.0, 1.0)
    flow = ModeFlow(system, "inside", np.array([0.0, 1.0]), 0.0, 0.2, LocalErrorEstimator("rk4"), t_end=3.0)
    n = 0
    while flow.point(n + 1) is not None:
        p0, p1 = flow.points[n], flow.points[n + 1]
        for s in np.linspace(0, 1, 9):
            x = flow.state(n, s)
            t = p0.t + s * (p1.t - p0.t)
            r = (1 - s) * p0.radius + s * p1.radius
            assert np.linalg.norm(x - ref.state(np.array([0.0, 1.0]), t)) <= r
        n += 1
    assert flow.points[-1].t == pytest.approx(3.0)


def test_bad_input_is_reported_by_name():
    system = linear(A_ROTATION)
    ex = simulate(system, X0, "m", 1.0, 0.1, 1e-3)
    with pytest.raises(SimulationError, match="no embedded error estimate"):
        error_bound(ex, system, pair="rk4")
    with pytest.raises(SimulationError, match="error floor must be finite and >= 0"):
        error_bound(ex, system, floor=-1.0)
    with pytest.raises(SimulationError, match="lipschitz must be 'max' or"):
        error_bound(ex, system, lipschitz="min")
    with pytest.raises(SimulationError, match=r"needs a legsim\.Execution"):
        error_bound("run.npz", system)
    with pytest.raises(SimulationError, match="ball dimension must be a positive integer"):
        ball_fraction_past(0.1, 1.0, 0)


def test_circular_reference_samples_match_a_relaxed_run_across_the_wall():
    ref = CircularReference(1.0, 1.0).with_initial("inside", [0.0, 1.5])
    times = np.linspace(0.0, 3.0, 31)
    ex = simulate(circular_flow(), [0.0, 1.5], "inside", 3.0, 1e-2, 1e-9)
    got, want = ex.sample(times), ref.sample(times)
    assert got.modes == want.modes == ["outside" if 1.5 * np.sin(t) > 1 else "inside" for t in times]
    assert np.allclose(np.array(got.states), np.array(want.states), atol=1e-7)


def test_linearised_distance_to_a_curved_guard_is_second_order_accurate():
    # Guard g = rho^2 - |x|^2 (inside the disc of radius rho): the linearised distance
    # g / |grad g| = (rho^2 - r^2) / (2 r) differs from the true rho - r by (rho - r)^2 / (2 r).
    from legsim import Transition
    from legsim.bounds import signed_distance

    rho = 2.0
    tr = Transition("a", "b", guard=lambda x: rho**2 - float(x @ x))  # gradient by finite differences
    for r in (1.9, 1.99, 1.999, 2.01):
        x = r * np.array([0.6, 0.8])
        assert signed_distance(tr, x) == pytest.approx(rho - r, abs=(rho - r) ** 2 / (2 * r) * 1.01 + 1e-9)
        assert abs(signed_distance(tr, x) - (rho - r)) >= (rho - r) ** 2 / (2 * r) * 0.99 - 1e-9


def test_bound_overflow_ends_the_flow_at_its_last_finite_ball():
    # sigma_max of this stable non-normal matrix is ~1000 1/s: B grows like e^(1000 t) and
    # overflows near t = 0.7 s. The flow must stop there with finite balls, not go on with
    # infinite ones (0 * inf = nan in every interpolated radius).
    A = np.array([[-1.0, 1000.0], [0.0, -1.0]])
    flow = ModeFlow(linear(A), "m", X0, 0.0, 0.01, LocalErrorEstimator("rk4"), t_end=5.0)
    n = 0
    while flow.step_samples(n) is not None:
        n += 1
    assert flow.status == "bound_overflow" and "overflowed" in flow.message
    radii = np.array([p.radius for p in flow.points])
    assert np.all(np.isfinite(radii)) and radii[-1] > 1e250
    assert 0.5 < flow.points[-1].t < 1.0  # 709 / 1000 s, give or take the local errors' size


def test_extrema_next_to_a_step_end_are_sampled():
    # The circle of radius 1 touches x1 = 1 at t = pi/2; started so that the tangency falls at
    # 95% of a step, the closest approach lies in the step's last sub-interval, where no sample
    # follows it inside the step. The samples must still hold the interpolant's minimum distance.
    from scipy.optimize import minimize_scalar

    h = 0.1
    t0 = math.pi / 2 - 15.95 * h
    x0 = CircularReference(1.0, 1.0).state(np.array([0.0, 1.0]), t0)
    flow = ModeFlow(circular_flow(), "inside", x0, t0, h, LocalErrorEstimator("rk4"), t_end=t0 + 3.0)
    smp = flow.step_samples(15)
    closest = minimize_scalar(
        lambda s: 1.0 - flow.state(15, s)[0], bounds=(0.9, 1.0), method="bounded", options={"xatol": 1e-12}
    )
    assert 0.94 < closest.x < 0.96
    # At the step's end the distance is ~h^2/800 = 1.25e-5 (the ball is 1.5e-5): without the
    # minimum among the samples a ball reaching half past the plane would be missed.
    assert smp.distance[-1, 0] > 1e-5
    # Both minimisations stop within ~1e-8 of the minimiser in s: ~1e-14 in distance, against
    # the 1.2e-5 by which the end sample misses it.
    assert smp.distance[:, 0].min() <= closest.fun + 1e-12
