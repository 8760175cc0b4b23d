"""Distances from a point to one piece of a crossing: to the guard piece itself (the entry of a
forward crossing) or to its reset image (the entry of a backward one), and the cheap lower
bounds of these distances that prune the walk search.

Exact for coordinate pieces (boxes), and for their images under affine resets (a convex least
squares problem over a box); a local SLSQP minimisation for guards of unknown shape.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable

import numpy as np
from scipy.optimize import lsq_linear

from .geometry import Edge, Piece, ScalarWithGradient
from .solvers import slsqp

#: A function of a guard point p returning (value, gradient (shape (n,))).
Objective = Callable[[np.ndarray], tuple[float, np.ndarray]]


def project_onto_piece(piece: Piece, x: np.ndarray, tol: float) -> tuple[float, np.ndarray] | None:
    """(distance, nearest point) from x to the piece (exact for a box, local SLSQP otherwise);
    None when no feasible point was found."""
    p0 = piece.clip(x)
    if piece.boxed or (piece.eq is None and piece.feasible(p0, tol)):
        return float(np.linalg.norm(p0 - x)), p0

    def fun(p: np.ndarray) -> tuple[float, np.ndarray]:
        d = p - x
        return float(d @ d), 2.0 * d

    p = _local_min(piece, fun, p0, tol, 1.0 + float(x @ x))
    return None if p is None else (float(np.linalg.norm(p - x)), p)


def project_onto_image(edge: Edge, piece: Piece, x: np.ndarray, tol: float) -> tuple[float, np.ndarray] | None:
    """(|R(p) - x|, p) for the guard point p of the piece whose reset image is nearest to x
    (exact for an affine R on a box); None when no feasible point was found."""
    free = piece.free
    if edge.affine is not None and piece.boxed and free.size:
        p = _affine_box_preimage(edge.affine, piece, x)
        return _image_gap(edge, p, x), p
    p = _image_start(edge, piece, x)
    if free.size == 0:
        return (_image_gap(edge, p, x), p) if piece.feasible(p, tol) else None

    def fun(q: np.ndarray) -> tuple[float, np.ndarray]:
        d = np.asarray(edge.reset(q), dtype=float) - x
        return float(d @ d), 2.0 * (edge.jacobian(q).T @ d)

    q = _local_min(piece, fun, p, tol, 1.0 + float(x @ x))
    return None if q is None else (_image_gap(edge, q, x), q)


def set_distance_bound(edge: Edge, piece: Piece, x: np.ndarray, guard_side: bool, tol: float) -> float:
    """Lower bound of the distance from x to the guard piece (guard_side) or to its reset image,
    used only to prune walks. Exact for coordinate pieces (with affine resets on the image side).
    For guards of unknown shape a projection would be a local minimisation as costly as the walk
    itself, so a cautious first-order estimate is used instead: about |g(x)| / |grad g| on the
    guard side (``_first_order_offset``);
    on the image side, for an affine reset, the distance from x to the reset's range combined
    with sigma_min times the guard offset of the least-squares preimage; 0 otherwise (no pruning).
    """
    if piece.boxed and (guard_side or edge.affine is not None):
        res = project_onto_piece(piece, x, tol) if guard_side else project_onto_image(edge, piece, x, tol)
        return math.inf if res is None else res[0]
    if guard_side:
        if piece.eq is None:
            return float(np.linalg.norm(piece.clip(x) - x))  # the box alone: a superset
        return _first_order_offset(piece.eq, x)
    if edge.affine is None or piece.eq is None:
        return 0.0
    A, r = edge.affine
    pre = np.linalg.lstsq(A, x - r, rcond=None)[0]
    off_range = float(np.linalg.norm(A @ pre + r - x))
    smallest = float(edge.sigma[0]) if edge.sigma is not None else 0.0
    return math.hypot(off_range, smallest * _first_order_offset(piece.eq, pre))


def piece_constraints(piece: Piece, free: np.ndarray, full: Callable[[np.ndarray], np.ndarray]) -> list[dict]:
    """The piece's equality and inequalities as scipy constraints on the free coordinates z
    (``full(z)`` is the guard point they give; gradients restricted to ``free``)."""
    cons = []
    if piece.eq is not None:
        g, dg = piece.eq
        cons.append({"type": "eq", "fun": lambda z: g(full(z)), "jac": lambda z: dg(full(z))[free]})
    for h, dh in piece.ineqs:
        cons.append({"type": "ineq", "fun": lambda z, h=h: h(full(z)), "jac": lambda z, dh=dh: dh(full(z))[free]})
    return cons


def _image_gap(edge: Edge, p: np.ndarray, x: np.ndarray) -> float:
    return float(np.linalg.norm(np.asarray(edge.reset(p), dtype=float) - x))


def _affine_box_preimage(affine: tuple[np.ndarray, np.ndarray], piece: Piece, x: np.ndarray) -> np.ndarray:
    """argmin over the box piece of |A p + r - x| (a convex least-squares problem)."""
    A, r = affine
    free = piece.free
    base = piece.clip(np.zeros(A.shape[1]))
    p = base.copy()
    p[free] = box_least_squares(A[:, free], x - r - A @ base, piece.lb[free], piece.ub[free])
    return piece.clip(p)


def _image_start(edge: Edge, piece: Piece, x: np.ndarray) -> np.ndarray:
    """A guard point to start the search from: the unconstrained least-squares preimage for an
    affine reset, else x itself when it has the source's dimension, clipped to the box."""
    free = piece.free
    base = piece.clip(np.zeros(edge.n_source))
    if edge.affine is None:
        return piece.clip(x if x.shape == (edge.n_source,) else base)
    if free.size == 0:
        return base
    A, r = edge.affine
    p = base.copy()
    p[free] = np.linalg.lstsq(A[:, free], x - r - A @ base, rcond=None)[0]
    return piece.clip(p)


def box_least_squares(A: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """argmin |A z - b| over lo <= z <= hi (a convex QP): closed form for one variable; else the
    unconstrained solution when it is feasible (then optimal), else bounded-variable LSQ."""
    if A.shape[1] == 1:
        a = A[:, 0]
        aa = float(a @ a)
        z = float(a @ b) / aa if aa > 0.0 else 0.0
        return np.array([min(max(z, lo[0]), hi[0])])
    z = np.linalg.lstsq(A, b, rcond=None)[0]
    if np.all(z >= lo) and np.all(z <= hi):
        return z
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return lsq_linear(A, b, bounds=(lo, hi), method="bvls", tol=1e-14).x


def _local_min(piece: Piece, fun: Objective, s0: np.ndarray, tol: float, scale: float) -> np.ndarray | None:
    """A feasible local minimum of fun(p) over the piece (SLSQP from a few starts): the first
    feasible result from the nearest starts, or from the axis starts when those give none."""
    free = piece.free
    for group in (_generic_starts(piece, s0), _axis_starts(piece, s0)):
        for start in group:
            start_copy = start.copy()

            def full(z: np.ndarray, base: np.ndarray = start_copy) -> np.ndarray:
                p = base.copy()
                p[free] = z
                return p

            def objective(z: np.ndarray, full: Callable[[np.ndarray], np.ndarray] = full) -> tuple[float, np.ndarray]:
                return _restrict(fun(full(z)), free)

            z = slsqp(
                objective,
                start[free],
                piece.lb[free],
                piece.ub[free],
                piece_constraints(piece, free, full),
                ftol=1e-14 * scale,
                maxiter=60,
            )
            if z is None:
                continue
            p = piece.clip(full(z))
            if not piece.feasible(p, tol):
                continue
            if fun(p)[0] < math.inf:
                return p  # a converged local search from the nearest start is the projection wanted
            break  # its value is not finite (the model's): try the next group of starts
    return None


def _restrict(value_grad: tuple[float, np.ndarray], free: np.ndarray) -> tuple[float, np.ndarray]:
    return value_grad[0], value_grad[1][free]


def _generic_starts(piece: Piece, s0: np.ndarray) -> list[np.ndarray]:
    """Starting points for a local search on a guard of unknown shape: the given point and its
    Newton step onto g = 0."""
    starts = [s0]
    if piece.eq is not None:
        g, dg = piece.eq
        try:
            value, grad = g(s0), np.asarray(dg(s0), dtype=float)
        except Exception:  # the model refused the probe: keep the plain start
            value, grad = math.nan, np.zeros(len(s0))
        norm2 = float(grad @ grad)
        if math.isfinite(value) and norm2 > 0.0 and np.all(np.isfinite(grad)):
            starts.append(piece.clip(s0 - value * grad / norm2))
    return starts


def _axis_starts(piece: Piece, s0: np.ndarray) -> list[np.ndarray]:
    """Points moved from s0 along each free coordinate, for where the nearest starts fail (e.g.
    where the guard's gradient vanishes, as at the centre of a circular guard)."""
    radius = 1.0 + float(np.max(np.abs(s0)))
    out = []
    for i in piece.free:
        for sign in (1.0, -1.0):
            e = np.zeros(len(s0))
            e[i] = sign * radius
            out.append(piece.clip(s0 + e))
    return out


def _first_order_offset(eq: ScalarWithGradient, x: np.ndarray) -> float:
    """A cautious estimate of the distance from x to {g = 0}: |g(x)| over the larger gradient
    norm at x and at its Newton point, halved. |g| / |grad g| alone overestimates where the
    gradient grows towards the guard (1 - |x|^2 seen from near the centre of the disk)."""
    g, dg = eq
    try:
        value, grad = float(g(x)), np.asarray(dg(x), dtype=float)
        norm = float(np.linalg.norm(grad))
        if not (math.isfinite(value) and math.isfinite(norm)) or norm == 0.0:
            return 0.0
        far = float(np.linalg.norm(np.asarray(dg(x - value * grad / (norm * norm)), dtype=float)))
    except Exception:  # the model refused the probe: no estimate, no pruning
        return 0.0
    if math.isfinite(far):
        norm = max(norm, far)
    return 0.5 * abs(value) / norm
