"""The piecewise-linear stability test on constructed maps whose answers are known, each checked
against the map itself iterated from many perturbations."""

from __future__ import annotations

import numpy as np
import pytest

from legsim.orbits.piecewise import Piece, stability

RIGHT = np.array([[1.0, 0.0]])  # delta_1 >= 0
LEFT = np.array([[-1.0, 0.0]])  # delta_1 <= 0


def iterate(pieces, delta, steps):
    """The map applied ``steps`` times: each step takes the piece whose region holds delta."""
    for _ in range(steps):
        k = next(i for i, p in enumerate(pieces) if np.all(p.C @ delta >= 0.0))
        delta = pieces[k].A @ delta
    return delta


def growth(pieces, steps=60, samples=200):
    """The largest norm ratio after ``steps`` iterations over random unit perturbations."""
    rng = np.random.default_rng(7)
    ratios = []
    for _ in range(samples):
        delta = rng.normal(size=2)
        delta /= np.linalg.norm(delta)
        ratios.append(np.linalg.norm(iterate(pieces, delta, steps)))
    return max(ratios)


def test_two_contracting_pieces_share_a_quadratic_lyapunov_function():
    pieces = [Piece(np.array([[0.5, 0.2], [0.0, 0.6]]), RIGHT), Piece(np.array([[0.5, 0.2], [0.1, 0.6]]), LEFT)]
    verdict = stability(pieces)
    assert verdict.kind == "stable" and verdict.details["length"] == 1
    assert growth(pieces) < 1e-6


def test_a_piece_whose_unstable_direction_stays_in_its_region_is_unstable():
    pieces = [Piece(np.diag([1.5, 0.5]), RIGHT), Piece(np.diag([0.5, 0.5]), LEFT)]
    verdict = stability(pieces)
    assert verdict.kind == "unstable" and verdict.details["growth"] == pytest.approx(1.5)
    assert growth(pieces) > 1e6


def test_stable_although_one_piece_alone_is_unstable():
    # A1 has eigenvalue -1.5 but sends its region (delta_1 > 0) into the other one, whose piece
    # contracts and sends it back: every two returns contract.
    A1 = np.array([[-1.5, 0.0], [1.0, 0.2]])
    A2 = np.array([[-0.2, 0.0], [0.0, 0.3]])
    assert max(abs(np.linalg.eigvals(A1))) > 1.0
    pieces = [Piece(A1, RIGHT), Piece(A2, LEFT)]
    verdict = stability(pieces)
    assert verdict.kind == "stable" and verdict.details["length"] == 2
    assert growth(pieces) < 1e-6


def test_unstable_although_each_piece_alone_is_stable():
    # Both pieces have spectral radius 0.2, but their shears, taken in the order the regions
    # impose, grow every three returns.
    A1 = np.array([[-0.2, 3.0], [0.0, -0.2]])
    A2 = np.array([[-0.2, 0.0], [-3.0, -0.2]])
    assert max(abs(np.linalg.eigvals(A1))) < 1.0 and max(abs(np.linalg.eigvals(A2))) < 1.0
    pieces = [Piece(A1, RIGHT, "a"), Piece(A2, LEFT, "b")]
    verdict = stability(pieces)
    assert verdict.kind == "unstable"
    assert growth(pieces) > 1e6


def test_a_rotation_is_left_unresolved():
    # An isometry: no contraction exists and no ray grows.
    R = np.array([[0.0, -1.0], [1.0, 0.0]])
    assert stability([Piece(R, RIGHT), Piece(R, LEFT)], max_length=2).kind == "unresolved"


# -- the pieces of a hybrid system's return map, at an orbit where two events coincide ---------
def two_switches(k, G):
    """u, v and a clock theta (theta' = 1). Event A fires when u + theta reaches 1/2, event B when
    v + theta does; after A, v grows at rate k, after B, u does; at theta = 1 the lap resets
    (u, v) to G (u - k/2, v - k/2) and theta to 0. On the orbit u = v = 0 both events fire at
    theta = 1/2 together. Along the lap u and v are piecewise linear in the start, so the return
    map is piecewise linear, continuous, with the pieces G L_A (u > v: A first) and G L_B in
    closed form (``closed_form_pieces``)."""
    from legsim import HybridSystem, Mode, Transition

    def mode(du, dv):
        return Mode(3, lambda t, x, u_: np.array([du, dv, 1.0]), names=("u", "v", "theta"))

    def event_a(x):
        return 0.5 - x[2] - x[0]

    def event_b(x):
        return 0.5 - x[2] - x[1]

    def lap(x):
        return np.concatenate([G @ (x[:2] - k / 2), [0.0]])

    return HybridSystem(
        {"none": mode(0.0, 0.0), "a": mode(0.0, k), "b": mode(k, 0.0), "ab": mode(k, k)},
        [
            Transition("none", "a", guard=event_a, name="A"),
            Transition("none", "b", guard=event_b, name="B"),
            Transition("b", "ab", guard=event_a, name="A"),
            Transition("a", "ab", guard=event_b, name="B"),
            Transition("ab", "none", guard=lambda x: 1.0 - x[2], reset=lap, name="lap"),
        ],
        name="two switches",
    )


def closed_form_pieces(k, G):
    """A first (u0 > v0): B fires at theta = 1/2 - (v0 + k u0) / (1 + k), and the lap ends with
    (u, v) - k/2 = L_A (u0, v0); B first by the mirror image."""
    L_A = np.array([[1 + k * k / (1 + k), k / (1 + k)], [k, 1.0]])
    L_B = L_A[::-1, ::-1]
    return [Piece(G @ L_A, np.array([[1.0, -1.0]]), "A first"), Piece(G @ L_B, np.array([[-1.0, 1.0]]), "B first")]


ROTATE = np.array([[0.0, -1.0], [1.0, 0.0]])


@pytest.mark.parametrize(
    "G, kind, returns",
    [
        # each piece's spectral radius 0.8, yet no common quadratic norm contracts both at once:
        # every three returns do.
        (0.8 * ROTATE, "stable", 40),
        # "A first" alone is unstable (spectral radius 1.145), but it sends its region where
        # "B first" (0.346) contracts: every three returns contract.
        (np.array([[-0.6, -0.6], [0.3, 0.1]]), "stable", 40),
        # "A first" alone is stable (0.849); "B first" has eigenvalue 1.293 along a direction that
        # stays where B fires first.
        (np.array([[0.0, -0.8], [0.9, 0.9]]), "unstable", 12),
    ],
)
def test_the_pieces_at_simultaneous_events_are_the_closed_form_ones_and_decide_stability(G, kind, returns):
    from legsim.orbits import OrbitProblem, Section, find_orbit
    from legsim.orbits.returns import ReturnMap

    k = 1.0
    expected = closed_form_pieces(k, G)
    truth = stability(expected)
    assert truth.kind == kind
    problem = OrbitProblem(
        two_switches(k, G), Section.level("none", "theta", 0.25, "increasing"), h=1e-2, eps=1e-10, t_max=3.0
    )
    result = find_orbit(problem, [0.0, 0.0, 0.25], jacobian="fd", fd_step=1e-5)
    assert result.converged and result.differentiable is False
    verdict = result.piecewise
    assert verdict.kind == kind and result.stable is (kind == "stable")
    assert verdict.details["orders"] == [["A", "B", "lap"], ["B", "A", "lap"]]
    # the boundary u = v, to the map's O(eps / d) accuracy
    assert np.allclose(verdict.details["normal"], [2**-0.5, -(2**-0.5), 0.0], atol=1e-6)
    # each piece's radius is the closed form's (the section's coordinates are a rotation of (u, v))
    closed = [float(max(abs(np.linalg.eigvals(p.A)))) for p in expected]
    assert verdict.details["piece_radii"] == pytest.approx(closed, rel=1e-5)
    if kind == "stable":
        assert verdict.details["length"] == truth.details["length"] == 3
    else:
        assert verdict.details["growth"] == pytest.approx(truth.details["growth"], rel=1e-5)
    # The hybrid system itself, iterated from small perturbations on either side.
    rmap = ReturnMap(problem)
    for start in ([1e-3, -2e-3], [-2e-3, 1e-3], [1e-3, 1.5e-3]):
        x = np.array([*start, 0.25])
        for _ in range(returns):
            x = rmap(x).x_end
        size = float(np.max(np.abs(x[:2])))
        assert size < 1e-6 if kind == "stable" else size > 5e-3  # from 1e-3: contracted 1e3 times, or grown 5
