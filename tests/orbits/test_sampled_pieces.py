"""The pieces of a return map where more than two event orders meet, found by sampling
(``legsim.orbits.sampled_pieces``), on constructed continuous piecewise-linear maps whose pieces
and verdicts are known in closed form.

The test bed: ``P(delta) = A delta + sum_k u_k max(c_k . delta, 0)``, continuous and piecewise
linear with one boundary hyperplane per k; its region of the signs s (s_k = c_k . delta > 0) has
the piece ``A + sum_{s_k} u_k c_k^T``. The event order of a return is the sign pattern.
"""

import numpy as np
import pytest

from legsim.orbits.piecewise import section_matrices
from legsim.orbits.sampled_pieces import PieceSampler, sampled_verdict

STEP = 1e-3
N = 4


def kinked_map(A, kinks, curvature=0.0):
    """(evaluate, the pieces by sign pattern) of the map above; ``curvature`` adds a smooth
    quadratic term curvature * |delta|^2 to every row (not piecewise linear)."""

    def evaluate(z):
        signs = tuple("+" if c @ z > 0 else "-" for _, c in kinks)
        out = A @ z + sum(u * max(c @ z, 0.0) for u, c in kinks) + curvature * float(z @ z)
        return out, signs

    def piece(signs):
        return A + sum(np.outer(u, c) for (u, c), s in zip(kinks, signs, strict=True) if s == "+")

    return evaluate, piece


def sampler_for(evaluate, A):
    zero = np.zeros(N)
    return PieceSampler(evaluate, zero, evaluate(zero)[0], range(N), np.full(N, STEP), A)


def as_is(matrices):
    return matrices


#: Three boundaries in general position (eight regions in R^4).
NORMALS = [np.array([1.0, 0.3, 0.0, -0.2]), np.array([0.2, -1.0, 0.5, 0.0]), np.array([0.0, 0.4, 1.0, 0.6])]


def test_every_region_gives_its_closed_form_piece():
    rng = np.random.default_rng(3)
    A = 0.3 * rng.standard_normal((N, N))
    kinks = [(0.2 * rng.standard_normal(N), c) for c in NORMALS]
    evaluate, piece = kinked_map(A, kinks)
    sampler = sampler_for(evaluate, A)
    regions = sampler.regions()
    assert len(regions) >= 6  # three hyperplanes through the origin of R^4: up to 8 regions
    for order, deltas in regions.items():
        found = sampler.piece(order, deltas)
        assert not isinstance(found, str), found
        np.testing.assert_allclose(found.A, piece(order), atol=1e-9)


def test_pieces_that_all_contract_in_one_norm_are_stable():
    # A's spectral radius 0.5 and kinks of size 0.15: every piece below 0.8 in the 2-norm.
    A = 0.5 * np.eye(N)
    evaluate, _ = kinked_map(A, [(np.array([0.1, 0.0, 0.05, 0.0]), c) for c in NORMALS])
    verdict = sampled_verdict(sampler_for(evaluate, A), as_is)
    assert verdict.kind == "stable", verdict.reason
    assert verdict.details["factor"] < 1.0


def test_a_piece_whose_growing_ray_stays_in_its_region_is_unstable():
    # Region c1 . delta > 0 has the piece diag(1.7, 0.5, 0.5, 0.5): e_1 lies inside it
    # (c1 . e_1 = 1) and grows by 1.7 a return.
    A = 0.5 * np.eye(N)
    kinks = [(np.array([1.2, 0.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0, 0.0])), (np.zeros(N), NORMALS[1])]
    evaluate, _ = kinked_map(A, kinks)
    verdict = sampled_verdict(sampler_for(evaluate, A), as_is)
    assert verdict.kind == "unstable", verdict.reason
    assert verdict.details["growth"] == pytest.approx(1.7, rel=1e-9)


def test_a_map_that_is_not_piecewise_linear_at_the_scale_is_unresolved():
    # A quadratic term that moves a return by 10% of its size at the sampling scale: the fresh
    # perturbations' returns miss their pieces' predictions.
    A = 0.5 * np.eye(N)
    evaluate, _ = kinked_map(A, [(np.array([0.1, 0.0, 0.0, 0.0]), c) for c in NORMALS], curvature=0.1 / STEP)
    verdict = sampled_verdict(sampler_for(evaluate, A), as_is)
    assert verdict.kind == "unresolved" and "prediction" in verdict.reason


def test_a_conserved_quantity_is_taken_out_as_the_trivial_multiplier():
    # Every piece conserves r . delta (r^T A_k = r^T): a family of fixed points, multiplier 1.
    # The pieces fix no common direction, so the quotient restricts them to r . delta = 0,
    # where they contract.
    r = np.array([1.0, -1.0, 0.0, 0.0]) / np.sqrt(2.0)
    rest = np.eye(N) - np.outer(r, r)
    A = np.outer(r, r) + 0.4 * rest
    kinks = [(rest @ np.array([0.0, 0.0, 0.2, 0.1]), c) for c in NORMALS]
    _, piece = kinked_map(A, kinks)
    matrices = [piece(signs) for signs in [("+", "+", "+"), ("-", "-", "-"), ("+", "-", "+")]]
    assert all(np.allclose(r @ M, r) for M in matrices)
    flow = np.array([0.0, 0.0, 0.0, 1.0])  # the section: the complement of the last coordinate
    found = section_matrices(matrices, flow, (), 1)
    assert not isinstance(found, str), found
    restricted, _, dimension = found
    assert dimension == 2
    assert max(np.max(np.abs(np.linalg.eigvals(M))) for M in restricted) < 1.0


def test_a_region_the_samples_missed_leaves_the_verdict_unresolved():
    # One sample finds one region of eight; the fresh perturbations of the check land in others.
    A = 0.5 * np.eye(N)
    evaluate, _ = kinked_map(A, [(np.array([0.1, 0.0, 0.05, 0.0]), c) for c in NORMALS])
    zero = np.zeros(N)
    sampler = PieceSampler(evaluate, zero, zero, range(N), np.full(N, STEP), A, samples=1)
    verdict = sampled_verdict(sampler, as_is)
    assert verdict.kind == "unresolved" and "no sample had" in verdict.reason
