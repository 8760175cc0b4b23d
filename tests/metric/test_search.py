"""The relaxed quotient metric on small systems with closed-form distances (paper 000, Sec. III):
``distance`` and ``shortest_path`` against closed forms, the metric axioms, the relaxation
bounds of Theorem 21, and strip points. The systems and their closed forms are described in
tests/helpers/metric_systems.py; the disk is checked against a brute-force search over the circle.
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from helpers.metric_systems import C, ball, disk, still, two_mode
from legsim import HybridSystem, Mode, Transition
from legsim.metric import AffineReset, CoordinateGuard, distance, shortest_path


def ball_closed_form(v1: float, v2: float, eps: float, c: float = C) -> float:
    return min(v1 + c * v2, c * abs(v1 - v2) + eps)


def two_mode_closed_form(p: np.ndarray, q: np.ndarray, eps: float) -> float:
    (x, y), (u, v, w) = p, q
    forward = math.hypot(1.0 - x + math.hypot(u, w), y - v) + eps
    back = (
        minimize_scalar(
            lambda s: math.sqrt((u + 1) ** 2 + (v + w - s) ** 2 / 2) + math.hypot(x, y - s),
            bounds=(-20.0, 20.0),
            method="bounded",
            options={"xatol": 1e-12},
        ).fun
        + eps
    )
    return min(forward, back)


def disk_brute_force(a: np.ndarray, b: np.ndarray, eps: float) -> float:
    """Direct chord, or one crossing of the rim either way, minimised over the angle."""

    def via(theta: float, forward: bool) -> float:
        e = np.array([math.cos(theta), math.sin(theta)])
        entry, exit_ = (e, -0.5 * e) if forward else (-0.5 * e, e)
        return float(np.linalg.norm(a - entry) + np.linalg.norm(exit_ - b))

    best = float(np.linalg.norm(a - b))
    thetas = np.linspace(-math.pi, math.pi, 3601)
    for forward in (True, False):
        values = [via(t, forward) for t in thetas]
        k = int(np.argmin(values))
        res = minimize_scalar(
            lambda t, forward=forward: via(t, forward),
            bounds=(thetas[max(k - 1, 0)], thetas[min(k + 1, 3600)]),
            method="bounded",
            options={"xatol": 1e-12},
        )
        best = min(best, res.fun + eps)
    return best


#: CI runs a fixed set of examples (reproducible runs, as the property tests do); LEGSIM_FULL=1
#: draws new ones each run, which is how counterexamples such as the last test's are found.
FULL = os.environ.get("LEGSIM_FULL") == "1"


# -- strategies ---------------------------------------------------------------------------------
coord = st.floats(-3.0, 3.0, allow_nan=False)
speed = st.floats(0.0, 4.0, allow_nan=False)
epsilons = st.sampled_from([0.0, 1e-3, 0.05, 0.3])


@st.composite
def ball_points(draw):
    kind = draw(st.sampled_from(["free", "guard", "image"]))
    if kind == "guard":
        return ("fall", np.array([0.0, -draw(speed)]))
    if kind == "image":
        return ("fall", np.array([0.0, draw(speed)]))
    return ("fall", np.array([draw(st.floats(-0.5, 3.0)), draw(coord)]))


@st.composite
def two_mode_points(draw):
    if draw(st.booleans()):
        return ("a", np.array([draw(st.floats(-2.0, 1.0)), draw(coord)]))
    return ("b", np.array([draw(st.floats(-1.0, 2.0)), draw(coord), draw(coord)]))


@st.composite
def disk_points(draw):
    r = draw(st.floats(0.0, 1.0))
    t = draw(st.floats(-math.pi, math.pi))
    return ("disk", np.array([r * math.cos(t), r * math.sin(t)]))


SYSTEMS = {"ball": (ball, ball_points), "two_mode": (two_mode, two_mode_points), "disk": (disk, disk_points)}


def _scale(*points) -> float:
    return 1.0 + sum(float(np.linalg.norm(p[1])) for p in points)


# -- closed forms ---------------------------------------------------------------------------------
@pytest.mark.parametrize("declared", [False, True])
@given(v1=speed, v2=speed, eps=epsilons)
@settings(max_examples=40, deadline=None, derandomize=not FULL)
def test_ball_guard_to_image_distance_matches_closed_form(declared, v1, v2, eps):
    system = ball(declared=declared)
    d = distance(system, ("fall", [0.0, -v1]), ("fall", [0.0, C * v2]), eps)
    assert d == pytest.approx(ball_closed_form(v1, v2, eps), abs=1e-9 * (1 + v1 + v2))


@pytest.mark.parametrize("declared", [False, True])
@given(p=two_mode_points(), q=two_mode_points(), eps=epsilons)
@settings(max_examples=40, deadline=None, derandomize=not FULL)
def test_two_mode_distance_across_dimensions_matches_unfolding(declared, p, q, eps):
    if p[0] == q[0]:
        return
    a, b = (p, q) if p[0] == "a" else (q, p)
    d = distance(two_mode(declared), a, b, eps)
    assert d == pytest.approx(two_mode_closed_form(a[1], b[1], eps), abs=1e-7 * _scale(a, b))


@given(p=disk_points(), q=disk_points(), eps=epsilons)
@settings(max_examples=25, deadline=None, derandomize=not FULL)
def test_disk_with_a_non_coordinate_guard_matches_brute_force(p, q, eps):
    d = distance(disk(), p, q, eps, max_hops=1)
    assert d == pytest.approx(disk_brute_force(p[1], q[1], eps), abs=1e-6)


# -- metric axioms ---------------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(SYSTEMS))
@given(data=st.data(), eps=epsilons)
@settings(max_examples=30, deadline=None, derandomize=not FULL)
def test_symmetry(name, data, eps):
    make, points = SYSTEMS[name]
    system = make()
    a, b = data.draw(points()), data.draw(points())
    assert distance(system, a, b, eps) == pytest.approx(distance(system, b, a, eps), abs=1e-8 * _scale(a, b))


@pytest.mark.parametrize("name", sorted(SYSTEMS))
@given(data=st.data(), eps=epsilons)
@settings(max_examples=20, deadline=None, derandomize=not FULL)
def test_triangle_inequality(name, data, eps):
    make, points = SYSTEMS[name]
    system = make()
    a, b, c = data.draw(points()), data.draw(points()), data.draw(points())
    # Paths of at most K crossings from a to b and from b to c join into one of at most 2 K:
    # the inequality the hop-capped search satisfies is d_2K(a, c) <= d_K(a, b) + d_K(b, c).
    # (With the same cap on the left it can fail: two_mode has pairs whose shortest path
    # needs 3 crossings.)
    tol = 1e-8 * _scale(a, b, c)  # the minimisations converge to ~1e-12 of the scale
    left = distance(system, a, c, eps, max_hops=4)
    assert left <= distance(system, a, b, eps, max_hops=2) + distance(system, b, c, eps, max_hops=2) + tol


@pytest.mark.parametrize("name", sorted(SYSTEMS))
@given(data=st.data(), eps=epsilons)
@settings(max_examples=30, deadline=None, derandomize=not FULL)
def test_guard_point_and_its_reset_image_are_eps_apart(name, data, eps):
    make, _ = SYSTEMS[name]
    system = make()
    tr = data.draw(st.sampled_from(system.transitions))
    if name == "ball":
        p = np.array([0.0, -data.draw(speed)])
    elif name == "two_mode":
        p = (
            np.array([1.0, data.draw(coord)])
            if tr.source == "a"
            else np.array([-1.0, data.draw(coord), data.draw(coord)])
        )
    else:
        t = data.draw(st.floats(-math.pi, math.pi))
        p = np.array([math.cos(t), math.sin(t)])
    image = np.asarray(tr.reset(p), dtype=float)
    d = distance(system, (tr.source, p), (tr.target, image), eps)
    # One crossing costs eps; in a self-transition the direct chord may be shorter still.
    expected = eps if tr.source != tr.target else min(eps, float(np.linalg.norm(p - image)))
    assert d == pytest.approx(expected, abs=1e-12 * _scale((tr.source, p)))


@given(a=ball_points(), b=ball_points(), eps=epsilons)
@settings(max_examples=40, deadline=None, derandomize=not FULL)
def test_positivity_between_distinct_classes_of_the_ball(a, b, eps):
    # Every crossing starts and ends on the line z = 0 (guard and image), so any path that
    # crosses is at least |z_a| + |z_b| + eps long: a bound independent of the search.
    d = distance(ball(), a, b, eps)
    direct = float(np.linalg.norm(a[1] - b[1]))
    bound = min(direct, abs(a[1][0]) + abs(b[1][0]) + eps)
    assert d >= bound - 1e-12
    assert d <= direct + 1e-12
    if bound > 0.0:  # then a and b are distinct classes (a guard point and its image have z = 0)
        assert d > 0.0


# -- relaxation: d_eps -> d_0 (Theorem 21) -----------------------------------------------------------
@pytest.mark.parametrize("name", sorted(SYSTEMS))
@given(data=st.data())
@settings(max_examples=20, deadline=None, derandomize=not FULL)
def test_relaxed_distance_is_between_d0_and_d0_plus_k_eps(name, data):
    make, points = SYSTEMS[name]
    system = make()
    a, b = data.draw(points()), data.draw(points())
    path0 = shortest_path(system, a, b, 0.0)
    tol = 1e-8 * _scale(a, b)
    previous = path0.length
    for eps in (1e-4, 1e-3, 1e-2, 1e-1):
        d = distance(system, a, b, eps)
        assert path0.length - tol <= d <= path0.length + path0.hops * eps + tol
        assert d >= previous - tol  # adding strips only lengthens paths
        previous = d


def test_relaxed_distance_converges_linearly_with_slope_the_number_of_crossings():
    # Ball: the shortest path from (0.3, -1) to (0.1, 0.7) crosses once (slope 1); two_mode
    # from a to b crosses once; the ball from guard side to guard side crosses twice ("fr":
    # bounce, slide along the image where distances shrink by c, bounce back).
    cases = [
        (ball(), ("fall", [0.3, -1.0]), ("fall", [0.1, 0.7]), 1),
        (two_mode(), ("a", [0.5, 0.2]), ("b", [0.3, -0.4, 0.1]), 1),
        (ball(), ("fall", [0.0, -1.0]), ("fall", [0.0, -3.0]), 2),
    ]
    eps = np.logspace(-6, -2, 9)
    for system, a, b, hops in cases:
        d0 = distance(system, a, b, 0.0)
        assert shortest_path(system, a, b, 0.0).hops == hops
        excess = np.array([distance(system, a, b, e) for e in eps]) - d0
        slope = np.polyfit(eps, excess, 1)[0]
        assert slope == pytest.approx(hops, rel=1e-6)


# -- strip points --------------------------------------------------------------------------------------
@given(v=st.floats(0.1, 3.0), frac=st.floats(0.0, 1.0), eps=st.sampled_from([1e-3, 0.05]))
@settings(max_examples=30, deadline=None, derandomize=not FULL)
def test_strip_point_is_tau_from_its_guard_point_and_eps_minus_tau_from_the_reset(v, frac, eps):
    system = ball()
    q = np.array([0.0, -v])
    tau = frac * eps
    point = ("fall", q, "bounce", tau)
    assert distance(system, point, ("fall", q), eps) == pytest.approx(tau, abs=1e-14)
    assert distance(system, point, ("fall", [0.0, C * v]), eps) == pytest.approx(eps - tau, abs=1e-14)
    other = ("fall", q + np.array([0.0, -0.01]), "bounce", eps - tau)
    # Inside the strip (metric (12): chord along the guard plus |tau - tau'|), out through the
    # guard ends, or out through the reset ends where the chord shrinks by c.
    expected = min(0.01 + abs(eps - 2 * tau), tau + 0.01 + (eps - tau), (eps - tau) + C * 0.01 + tau)
    assert distance(system, point, other, eps) == pytest.approx(expected, abs=1e-12)


def test_different_modes_without_a_path_within_the_hop_cap_are_infinitely_far():
    assert distance(two_mode(), ("a", [0.0, 0.0]), ("b", [0.0, 0.0, 0.0]), 0.1, max_hops=0) == math.inf
    assert distance(two_mode(), ("a", [0.0, 0.0]), ("a", [0.0, 1.0]), 0.1, max_hops=0) == 1.0


def test_shortest_path_reports_its_crossing_on_the_guard():
    path = shortest_path(ball(), ("fall", [0.3, -1.0]), ("fall", [0.1, 0.7]), 0.01)
    (crossing,) = path.crossings
    assert crossing.name == "bounce" and crossing.forward
    assert crossing.point[0] == 0.0 and crossing.point[1] <= 0.0
    # The unfolded straight line: legs |(0.3, -1) - p| and |(0, -C p_zd) - (0.1, 0.7)|.
    legs = np.linalg.norm(np.array([0.3, -1.0]) - crossing.point) + np.linalg.norm(
        np.array([0.0, -C * crossing.point[1]]) - [0.1, 0.7]
    )
    assert path.length == pytest.approx(legs + 0.01, abs=1e-12)


# -- positivity and closed form with two different modes ---------------------------------------------
# shift: modes l = (x, y), domain x <= 1, and r = (u, v) (no transitions out: the whole plane).
# l->r at the coordinate hyperplane x = 1 with the translation (x, y) -> (x - 1, y + 2), so the
# guard point (1, s) is identified with (0, s + 2). From a = (x, y) in l to b = (u, v) in r the
# one crossing costs min over s of |(1 - x, y - s)| + |(u, s + 2 - v)| + eps; reflecting b's leg
# to the far side of the line (a translation and a reflection are isometries) makes it one
# straight segment: hypot(1 - x + |u|, y + 2 - v) + eps. Within a mode the chord is shortest: a
# detour l -> r -> l crosses the same line twice and, unfolded, is a broken path between the same
# ends (and r has no guard). Two states are the same point of the quotient space iff equal, or
# (1, s) in l and (0, s + 2) in r.
SHIFT = np.array([-1.0, 2.0])


def shift(declared: bool = False) -> HybridSystem:
    guard = CoordinateGuard((0, -1.0, 1.0)) if declared else (lambda x: 1.0 - x[0])
    reset = AffineReset(np.eye(2), SHIFT) if declared else (lambda x: np.asarray(x, dtype=float) + SHIFT)
    return HybridSystem(
        {"l": Mode(2, still, names=("x", "y")), "r": Mode(2, still, names=("u", "v"))},
        [Transition("l", "r", guard=guard, reset=reset, name="shift")],
        name="shift",
    )


def shift_closed_form(a, b, eps: float) -> float:
    (ma, pa), (mb, pb) = a, b
    if ma == mb:
        return float(np.linalg.norm(pa - pb))
    (x, y), (u, v) = (pa, pb) if ma == "l" else (pb, pa)
    return math.hypot(1.0 - x + abs(u), y + 2.0 - v) + eps


def _same_class(a, b) -> bool:
    (ma, pa), (mb, pb) = a, b
    if ma == mb:
        return bool(np.array_equal(pa, pb))
    (x, y), (u, v) = (pa, pb) if ma == "l" else (pb, pa)
    return x == 1.0 and u == 0.0 and v == y + 2.0


offset = st.sampled_from([0.0, 1e-6, -1e-3, 0.25])


@st.composite
def shift_pairs(draw):
    """Free pairs in either mode, and pairs straddling the guard: a guard point (1, s) against its
    image (0, s + 2) moved by small offsets (all zero: the same class)."""
    kind = draw(st.sampled_from(["free", "free", "straddle", "same-mode-near"]))
    if kind == "straddle":
        s = draw(coord)
        a = ("l", np.array([1.0 - abs(draw(offset)), s]))
        b = ("r", np.array([draw(offset), s + 2.0 + draw(offset)]))
    elif kind == "same-mode-near":
        m = draw(st.sampled_from(["l", "r"]))
        p = np.array([draw(st.floats(-2.0, 1.0)), draw(coord)])
        a, b = (m, p), (m, p + np.array([-abs(draw(offset)), draw(offset)]))
    else:

        def point():
            if draw(st.booleans()):
                return ("l", np.array([draw(st.floats(-2.0, 1.0)), draw(coord)]))
            return ("r", np.array([draw(st.floats(-2.0, 2.0)), draw(coord)]))

        a, b = point(), point()
    return (b, a) if draw(st.booleans()) else (a, b)


@pytest.mark.parametrize("declared", [False, True])
@given(pair=shift_pairs(), eps=epsilons)
@settings(max_examples=40, deadline=None, derandomize=not FULL)
def test_positivity_and_closed_form_between_two_different_modes(declared, pair, eps):
    a, b = pair
    d = distance(shift(declared), a, b, eps)
    # Exact (the guard is a coordinate hyperplane and the reset a translation, so the crossing
    # point is found by a convex minimisation, not a generic search): 1e-9 absolute.
    assert d == pytest.approx(shift_closed_form(a, b, eps), abs=1e-9)
    if _same_class(a, b):
        assert d == pytest.approx(0.0 if a[0] == b[0] else eps, abs=1e-12)
    elif shift_closed_form(a, b, eps) > 1e-150:
        # Distinct classes are apart. Below ~1e-154 the library's squared lengths underflow (it
        # returns 0.0 for points 1e-200 apart in any system, the ball too): a float limit, kept
        # out of this check and reported.
        assert d > 0.0


def test_symmetry_from_a_point_on_the_image_of_a_projection():
    # a = (0, 0) in mode a is R(q) for every guard point q = (-1, v, -v) of b->a; b = (-1, 0, 1)
    # lies on that guard. The shortest path goes to q = (-1, -0.5, 0.5), 0.7071 from b, whose
    # image is a: d = 1/sqrt 2 (the closed form). From a, the greedy starts lie on a kink of the
    # sum of norms (a zero-length leg), where SLSQP stops just beside the kink and reports
    # convergence: the walk must then be left to the barrier method (walk._smooth_minimum).
    system = two_mode()
    a, b = ("a", np.array([0.0, 0.0])), ("b", np.array([-1.0, 0.0, 1.0]))
    exact = two_mode_closed_form(a[1], b[1], 0.0)
    assert distance(system, b, a, 0.0) == pytest.approx(exact, abs=1e-9)
    assert distance(system, a, b, 0.0) == pytest.approx(exact, abs=1e-9)
