"""Stability of a piecewise-linear return map: the Bouligand derivative of a gait at simultaneous
events.

At a gait whose events happen together (a pronk's two feet), the order of the events switches
across the orbit, the return map is not differentiable there, and its derivative is
piecewise linear (Burden, Revzen, Sastry and Koditschek, SIAM J. Appl. Dyn. Syst. 2016): a
perturbation delta returns as ``A_k delta`` in region k, the set of perturbations whose events
happen in order k, a polyhedral cone ``{delta: C_k delta >= 0}``. Its eigenvalues alone decide
nothing: a piece's unstable direction may leave its region at once, and stable pieces may
alternate into growth. This module gives a verdict with a sufficient condition either way:

* **stable**: every sequence of L pieces that a perturbation can actually follow (its regions
  visited in turn: a linear feasibility problem) multiplies the perturbation's norm
  ``|delta|_P = sqrt(delta^T P delta)`` by less than 1; then every trajectory contracts by that
  factor every L returns. P is found as a common quadratic Lyapunov function when there is one
  (L = 1), else by a descent on the worst product's norm.
* **unstable**: a feasible periodic sequence of pieces has a real eigenvalue > 1 whose
  eigenvector follows that sequence's regions itself: the ray grows without end.
* **unresolved**: neither holds up to the lengths tried.

Regions are cones in the perturbation space; the test is exact for the piecewise-linear map
and, like the multipliers of a smooth orbit, about the gait's perturbations small enough for it
to hold.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linprog, minimize

#: Longest sequence of pieces tried.
MAX_LENGTH = 4
#: A perturbation counts as inside a region when every constraint holds to this margin (the
#: feasibility problem normalises the perturbation's size to 1 in the max norm).
MARGIN = 1e-9


@dataclass(frozen=True)
class Piece:
    """One linear piece: the map ``A`` on the region ``{delta: C delta >= 0}`` (C: rows of
    constraints, shape (m, n); no rows: everywhere)."""

    A: np.ndarray
    C: np.ndarray
    label: str = ""


@dataclass(frozen=True)
class Verdict:
    """The piecewise-linear map's stability: ``kind`` (``stable``, ``unstable``, ``unresolved``),
    why in words, and the numbers behind it (the sequence length L and contraction factor of a
    stable verdict; the sequence and its growth factor of an unstable one)."""

    kind: str
    reason: str
    details: dict[str, object] = field(default_factory=dict)


def feasible(pieces: list[Piece], sequence: tuple[int, ...]) -> bool:
    """Whether some perturbation follows ``sequence``: it lies in the first piece's region, its
    image in the second's, and so on (a linear program over the cone, normalised)."""
    n = pieces[0].A.shape[0]
    rows, product = [], np.eye(n)
    for k in sequence:
        piece = pieces[k]
        if piece.C.size:
            rows.append(piece.C @ product)
        product = piece.A @ product
    if not rows:
        return True
    G = np.vstack(rows)
    # maximise the least margin s: G delta >= s, -1 <= delta <= 1; feasible when s > 0.
    c = np.zeros(n + 1)
    c[-1] = -1.0
    A_ub = np.hstack([-G, np.ones((G.shape[0], 1))])
    result = linprog(c, A_ub=A_ub, b_ub=np.zeros(G.shape[0]), bounds=[(-1.0, 1.0)] * n + [(None, 1.0)])
    return bool(result.status == 0 and result.fun is not None and -result.fun > MARGIN)


def product_of(pieces: list[Piece], sequence: tuple[int, ...]) -> np.ndarray:
    """A_{k_L} ... A_{k_1} of the sequence (k_1 first)."""
    out = np.eye(pieces[0].A.shape[0])
    for k in sequence:
        out = pieces[k].A @ out
    return out


def p_norm(M: np.ndarray, L: np.ndarray) -> float:
    """The norm of M in the metric |delta|_P with P = L^T L: the spectral norm of L M L^-1."""
    return float(np.linalg.norm(L @ M @ np.linalg.inv(L), 2))


def contraction(products: list[np.ndarray]) -> tuple[float, np.ndarray]:
    """(the smallest worst-case norm found, its factor L of P = L^T L) over the products: from
    the identity, then by descent on L's upper triangle."""
    n = products[0].shape[0]
    best_L = np.eye(n)
    best = max(p_norm(M, best_L) for M in products)
    if best < 1.0:
        return best, best_L
    index = np.triu_indices(n)

    def worst(theta: np.ndarray) -> float:
        L = np.zeros((n, n))
        L[index] = theta
        if np.min(np.abs(np.diag(L))) < 1e-8:
            return np.inf
        return max(p_norm(M, L) for M in products)

    start = np.eye(n)[index]
    result = minimize(worst, start, method="Nelder-Mead", options={"maxiter": 4000 * n, "xatol": 1e-10, "fatol": 1e-12})
    if result.fun < best:
        L = np.zeros((n, n))
        L[index] = result.x
        best, best_L = float(result.fun), L
    return best, best_L


def growing_ray(pieces: list[Piece], sequence: tuple[int, ...]) -> float | None:
    """The growth factor of a ray that follows ``sequence`` periodically: a real eigenvalue
    > 1 of the sequence's product whose eigenvector (or its negative) visits the sequence's
    regions in turn; None when there is none."""
    values, vectors = np.linalg.eig(product_of(pieces, sequence))
    for value, vector in zip(values, vectors.T, strict=True):
        if abs(value.imag) > 1e-12 or value.real <= 1.0:
            continue
        for sign in (1.0, -1.0):
            delta = sign * vector.real
            if _follows(pieces, sequence, delta):
                return float(value.real)
    return None


def _follows(pieces: list[Piece], sequence: tuple[int, ...], delta: np.ndarray) -> bool:
    scale = float(np.max(np.abs(delta)))
    for k in sequence:
        piece = pieces[k]
        if piece.C.size and np.any(piece.C @ delta < -MARGIN * scale):
            return False
        delta = piece.A @ delta
        scale = float(np.max(np.abs(delta)))
    return True


def stability(pieces: list[Piece], max_length: int = MAX_LENGTH) -> Verdict:
    """The verdict on the piecewise-linear map of ``pieces`` (module docstring)."""
    if not pieces:
        raise ValueError("a piecewise-linear map needs at least one piece")
    for length in range(1, max_length + 1):
        sequences = [s for s in itertools.product(range(len(pieces)), repeat=length) if feasible(pieces, s)]
        for sequence in sequences:
            if sequence == _smallest_rotation(sequence):
                grows = growing_ray(pieces, sequence)
                if grows is not None:
                    labels = [pieces[k].label or str(k) for k in sequence]
                    return Verdict(
                        "unstable",
                        f"perturbations that follow the pieces {labels} periodically grow by {grows:.6g} per cycle",
                        {"sequence": labels, "growth": grows},
                    )
        factor, L = contraction([product_of(pieces, s) for s in sequences])
        if factor < 1.0:
            return Verdict(
                "stable",
                f"every {length} returns contract every feasible perturbation by at least {factor:.6g} in a "
                f"quadratic norm",
                {"length": length, "factor": factor, "P": (L.T @ L).tolist()},
            )
    return Verdict(
        "unresolved",
        f"neither a contraction nor a growing ray was found over sequences of up to {max_length} pieces",
        {"length": max_length},
    )


def _smallest_rotation(sequence: tuple[int, ...]) -> tuple[int, ...]:
    """The rotation of a periodic sequence that sorts first (each cycle is tried once)."""
    return min(sequence[i:] + sequence[:i] for i in range(len(sequence)))
