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

The pieces of a return map at an orbit (``pieces_at_orbit``)
-----------------------------------------------------------
The finite-difference Jacobian's stencil (``legsim.orbits.kinks``) already evaluates the map
at x +- d e_j for every coordinate j and records which transitions each return took. Where two
event orders O1 and O2 meet at the orbit, the one-sided difference towards a side is the piece
of that side's order applied to e_j: piece k's column j is the forward difference when
x + d e_j produced order k, the backward one when x - d e_j did, the central one when both
sides produced the same order (the column lies along the boundary). A continuous map's two
pieces agree on the boundary hyperplane ``c . delta = 0``, so ``A_1 - A_2 = u c^T`` has rank
one and its row gives the boundary's normal c (signed so that order O1 lies on c . delta > 0);
the extraction checks both (rank one to ``RANK_ONE``, every column's side consistent with c's
sign) and says why when they fail. Saltation matrices would give the same pieces for the state
alone; the finite differences also follow a controller's memory, which changes at transitions as
a function of the whole stance. The pieces are restricted to the section as the Floquet
multipliers are (cyclic coordinates out, then the complement of the flow direction, which lies
on the boundary: both event times move with it), and the multipliers known to be 1
(``trivial_multipliers``) are quotiented out when they belong to a subspace that both pieces fix
and that lies on the boundary. Only two orders are extracted: more than two, or a jump of the
map (no pieces at all), is an "unresolved" verdict naming the reason.
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.linalg import LinAlgWarning, solve_discrete_lyapunov
from scipy.optimize import linprog, minimize

#: Longest sequence of pieces tried.
MAX_LENGTH = 4
#: Largest dimension on which the norm descent (Nelder-Mead over P's factor) runs; above it only
#: the identity and Lyapunov-equation candidates are tried.
MAX_DESCENT_DIMENSION = 6
#: The pieces' difference counts as rank one when its second singular value is below this share
#: of its first (finite differences of step d leave O(d) curvature in each column).
RANK_ONE = 0.05
#: Relative size below which a common eigenvalue-1 direction of the pieces counts as one.
TRIVIAL_TOL = 1e-4
#: Where between the products' mean's spectral radius and 1 its scaled Lyapunov candidates put
#: their bound (``_lyapunov_factors``).
MEAN_MARGINS = (0.05, 0.25, 0.5)
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

    @property
    def stable(self) -> bool | None:
        """True, False or None (unresolved)."""
        return {"stable": True, "unstable": False}.get(self.kind)

    def to_json(self) -> dict[str, Any]:
        return {"verdict": self.kind, "reason": self.reason, "details": self.details}


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


def _lyapunov(M: np.ndarray) -> np.ndarray | None:
    """P solving ``M^T P M - P = -I``; None where the solver finds the system singular (a
    nilpotent-like M: the identity candidate already covers it)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LinAlgWarning)
        try:
            P = solve_discrete_lyapunov(M.T, np.eye(M.shape[0]))
        except np.linalg.LinAlgError:
            return None
    return P if np.all(np.isfinite(P)) else None


def _lyapunov_factors(products: list[np.ndarray]) -> list[np.ndarray]:
    """Candidate factors L (P = L^T L): each contracting product's solution of
    ``M^T P M - P = -I``, that of their sum (a common Lyapunov function when one exists near
    it), and the solutions for the products' mean scaled to a spectral radius just below 1
    (``MEAN_MARGINS``: M/s contracts in its own P by sqrt(1 - 1/|P|), so M by less than s,
    leaving the products' spread around their mean a margin of 1 - s to stay contracting)."""
    candidates, total = [], np.zeros_like(products[0])
    for M in products:
        if np.max(np.abs(np.linalg.eigvals(M))) >= 1.0:
            continue
        P = _lyapunov(M)
        if P is None:
            continue
        total = total + P / np.max(np.abs(P))
        candidates.append(P)
    if candidates:
        candidates.append(total)
    mean = np.mean(products, axis=0)
    radius = float(np.max(np.abs(np.linalg.eigvals(mean))))
    if radius < 1.0:
        for share in MEAN_MARGINS:
            P = _lyapunov(mean / (radius + share * (1.0 - radius)))
            if P is not None:
                candidates.append(P)
    factors = []
    for P in candidates:
        try:
            factors.append(np.linalg.cholesky(0.5 * (P + P.T)).T)
        except np.linalg.LinAlgError:
            continue
    return factors


def contraction(products: list[np.ndarray]) -> tuple[float, np.ndarray]:
    """(the smallest worst-case norm found, its factor L of P = L^T L) over the products: from
    the identity and the Lyapunov-equation candidates, then (up to ``MAX_DESCENT_DIMENSION``)
    by descent on L's upper triangle."""
    n = products[0].shape[0]
    best_L = np.eye(n)
    best = max(p_norm(M, best_L) for M in products)
    for L in _lyapunov_factors(products):
        norm = max(p_norm(M, L) for M in products)
        if norm < best:
            best, best_L = norm, L
    if best < 1.0 or n > MAX_DESCENT_DIMENSION:
        return best, best_L
    index = np.triu_indices(n)

    def worst(theta: np.ndarray) -> float:
        L = np.zeros((n, n))
        L[index] = theta
        if np.min(np.abs(np.diag(L))) < 1e-8:
            return np.inf
        return max(p_norm(M, L) for M in products)

    start = best_L[index]
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
        if not sequences:
            # No perturbation follows L pieces inside their regions (they are sent onto region
            # boundaries): no product to bound at this length.
            continue
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


def pieces_at_orbit(
    forward: np.ndarray,
    backward: np.ndarray,
    central: np.ndarray,
    orders: dict[int, tuple[tuple[str, ...], tuple[str, ...]]],
    field_at_orbit: np.ndarray,
    cyclic: Sequence[int] = (),
    trivial: int = 0,
) -> tuple[list[Piece], dict[str, Any]] | str:
    """The return map's two pieces at an orbit where two event orders meet, on the section and
    without the trivial multipliers (module docstring), with what was found on the way
    (``orders``, ``normal``, ``rank_ratio``, ``quotient``); or the reason there are none.

    forward, backward, central: the one-sided and central finite-difference Jacobians, (n, n);
    orders: for each checked column, the transitions of the returns from x + d e_j and x - d e_j;
    field_at_orbit: the (augmented) field at the orbit, (n,); cyclic: cyclic coordinates;
    trivial: multipliers known to be 1 to quotient out."""
    seen = sorted({order for pair in orders.values() for order in pair})
    if len(seen) != 2:
        return (
            f"{len(seen)} transition order(s) among the stencil's returns ({_orders_text(seen)}); pieces are "
            f"extracted where exactly two meet"
        )
    first, second = seen
    A1, A2 = central.copy(), central.copy()
    side = np.zeros(central.shape[1])
    for j, (plus, minus) in orders.items():
        if plus == minus:
            continue
        side[j] = 1.0 if plus == first else -1.0
        A1[:, j], A2[:, j] = (forward[:, j], backward[:, j]) if plus == first else (backward[:, j], forward[:, j])
    _, sv, Vt = np.linalg.svd(A1 - A2)
    ratio = float(sv[1] / sv[0]) if sv.size > 1 and sv[0] > 0 else 0.0
    if sv[0] == 0.0 or ratio > RANK_ONE:
        return (
            f"the one-sided differences of the two orders do not differ by a rank-one matrix (singular values "
            f"{sv[0]:.3g}, {sv[1] if sv.size > 1 else 0.0:.3g}): they are not two linear pieces meeting on a "
            f"hyperplane (a jump of the map, or a kink away from the orbit)"
        )
    normal = Vt[0] * np.sign(float(Vt[0] @ side) or 1.0)
    wrong = [j for j in orders if side[j] * normal[j] < -RANK_ONE * np.max(np.abs(normal))]
    if wrong:
        return f"the sides of column(s) {wrong} contradict the boundary normal the pieces' difference gives"
    on_section, info = _on_section([A1, A2], normal, field_at_orbit, cyclic, trivial)
    if isinstance(on_section, str):
        return on_section
    labels = (_orders_text([first]), _orders_text([second]))
    pieces = [Piece(A, C, label) for (A, C), label in zip(on_section, labels, strict=True)]
    info.update({"orders": [list(first), list(second)], "normal": normal.tolist(), "rank_ratio": ratio})
    return pieces, info


def _orders_text(orders: Sequence[tuple[str, ...]]) -> str:
    return "; ".join(", ".join(order) for order in orders)


def _on_section(
    matrices: list[np.ndarray], normal: np.ndarray, f: np.ndarray, cyclic: Sequence[int], trivial: int
) -> tuple[list[tuple[np.ndarray, np.ndarray]], dict[str, Any]] | tuple[str, dict[str, Any]]:
    """The two pieces (A_k, C_k) in coordinates of the section (``section_matrices``), the
    region of the second the other side of the boundary's; or (reason, {})."""
    keep = [i for i in range(len(f)) if i not in set(cyclic)]
    fk = np.asarray(f, dtype=float)[keep]
    if abs(float(normal[keep] @ fk)) > RANK_ONE * np.linalg.norm(normal[keep]) * np.linalg.norm(fk):
        return "the flow direction crosses the boundary between the orders (the pieces do not share it)", {}
    found = section_matrices(matrices, f, cyclic, trivial, normal)
    if isinstance(found, str):
        return found, {}
    (first, second), c, dimension = found
    return [(first, c), (second, -c)], {"quotient": trivial, "dimension": dimension}


def section_matrices(
    matrices: list[np.ndarray], f: np.ndarray, cyclic: Sequence[int], trivial: int, normal: np.ndarray | None = None
) -> tuple[list[np.ndarray], np.ndarray, int] | str:
    """The pieces' matrices in coordinates of the section (``floquet_multipliers``' basis of the
    flow's complement, cyclic coordinates out) with the ``trivial`` multipliers 1 taken out, the
    boundary ``normal`` in those coordinates (as a row, (1, k); empty without one) and their
    dimension k; or the reason there are none. The multipliers 1 are taken out as directions
    every piece fixes (on the boundary, with a normal); else, without a normal, as quantities
    every piece conserves (r^T A_k = r^T: each A_k maps the level set r^T delta = 0 into itself,
    and the pieces are restricted to it)."""
    keep = [i for i in range(len(f)) if i not in set(cyclic)]
    fk = np.asarray(f, dtype=float)[keep]
    Q, _ = np.linalg.qr(fk.reshape(-1, 1), mode="complete")
    B = Q[:, 1:]
    Ms = [B.T @ A[np.ix_(keep, keep)] @ B for A in matrices]
    c = np.zeros(B.shape[1]) if normal is None else B.T @ normal[keep]
    W = np.eye(B.shape[1])
    if trivial:
        taken = _common_unit_directions(Ms, trivial, transpose=False)
        if isinstance(taken, np.ndarray) and np.any(np.abs(c @ taken) > RANK_ONE * np.linalg.norm(c)):
            taken = "fixed off the boundary"
        if isinstance(taken, str) and normal is None:
            # without a boundary, quantities every piece conserves may take the multipliers 1
            conserved = _common_unit_directions(Ms, trivial, transpose=True)
            taken = conserved if isinstance(conserved, np.ndarray) else f"{taken}; of [A_k^T - I]: {conserved}"
        if isinstance(taken, str):
            kind = "on their boundary" if normal is not None else "nor quantities all pieces conserve"
            return (
                f"the {trivial} trivial multiplier(s) 1 are no directions all pieces fix {kind} (smallest "
                f"singular values of [A_k - I]: {taken})"
            )
        W = np.linalg.svd(taken, full_matrices=True)[0][:, trivial:]
    rows = np.empty((0, W.shape[1])) if normal is None else (W.T @ c).reshape(1, -1)
    return [W.T @ M @ W for M in Ms], rows, int(W.shape[1])


def _common_unit_directions(matrices: list[np.ndarray], count: int, transpose: bool) -> np.ndarray | str:
    """``count`` orthonormal directions (columns, (k, count)) that every matrix fixes (or, with
    ``transpose``, that every transposed matrix fixes: linear quantities every matrix conserves);
    else the smallest singular values of the stacked [A_k - I] in words."""
    stacked = np.vstack([(M.T if transpose else M) - np.eye(M.shape[0]) for M in matrices])
    _, sv, Vt = np.linalg.svd(stacked)
    scale = max(1.0, float(np.max(np.abs(stacked))))
    small = sv[-count:]
    if np.any(small > TRIVIAL_TOL * scale):
        return ", ".join(f"{v:.3g}" for v in small)
    return Vt[-count:].T


def piecewise_verdict(
    forward: np.ndarray,
    backward: np.ndarray,
    central: np.ndarray,
    orders: dict[int, tuple[tuple[str, ...], tuple[str, ...]]],
    field_at_orbit: np.ndarray,
    cyclic: Sequence[int] = (),
    trivial: int = 0,
) -> Verdict:
    """``stability`` of the pieces ``pieces_at_orbit`` extracts, or "unresolved" with the reason
    there are none; the verdict's details add the pieces' own spectral radii."""
    found = pieces_at_orbit(forward, backward, central, orders, field_at_orbit, cyclic, trivial)
    if isinstance(found, str):
        return Verdict("unresolved", f"no piecewise-linear derivative: {found}", {})
    pieces, info = found
    verdict = stability(pieces)
    radii = [float(np.max(np.abs(np.linalg.eigvals(p.A)))) if p.A.size else 0.0 for p in pieces]
    details = dict(verdict.details)
    details.update(info)
    details["piece_radii"] = radii
    return Verdict(verdict.kind, verdict.reason, details)
