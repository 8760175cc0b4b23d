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
